"""Issue 18 in the real window: slice views with zoom, pan and one big view; the crosshair in 3D; oblique
reformatting; measurements exact on a volume of known geometry; ROI statistics against NumPy; label maps."""

from __future__ import annotations

import numpy as np
import pytest
from qtpy.QtCore import QPointF, Qt

from app.slices import plane_frame, plane_grid, sample_plane

from .conftest import open_and_wait, wait_ready
from .gui_helpers import MARKERS, drag, marker_file, marker_volume, mouse, wheel, widget_image


def _blob_centres(view, count: int) -> list[np.ndarray]:
    """Centroids (widget pixels, x then y) of the bright grey blobs the view shows - found in its picture."""
    from scipy import ndimage

    image = widget_image(view).astype(int)
    viewport = view.viewport()
    grey = (np.abs(image[..., 0] - image[..., 1]) < 6) & (np.abs(image[..., 1] - image[..., 2]) < 6)
    bright = grey & (image.min(axis=2) > 128)
    mask = np.zeros_like(bright)
    top, left = int(viewport.top()) + 1, int(viewport.left()) + 1
    mask[top:int(viewport.bottom()) - 1, left:int(viewport.right()) - 1] = True
    labels, found = ndimage.label(bright & mask)
    sizes = ndimage.sum(np.ones_like(labels), labels, range(1, found + 1))
    largest = np.argsort(sizes)[::-1][:count] + 1
    weights = image.mean(axis=2) * (labels > 0)
    centres = ndimage.center_of_mass(weights, labels, largest)
    return [np.array([c[1] + 0.5, c[0] + 0.5]) for c in centres]  # pixel (row, col) centre -> (x, y)


def _match(centres, view) -> dict:
    """Which blob is which marker (nearest to where the view should draw it)."""
    volume = view.volume
    named = {}
    for name, ijk in MARKERS.items():
        expected = view.world_to_widget(volume.index_to_world(ijk))
        named[name] = min(centres, key=lambda c: np.hypot(c[0] - expected.x(), c[1] - expected.y()))
    return named


def _open_markers(qtbot, window, tmp_path):
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-cpu")
    open_and_wait(qtbot, window, marker_file(tmp_path))
    volume = window.model.base_volume
    window.model.set_window_level(600.0, 400.0)  # the balls white, the background black
    window.model.set_cursor(volume.index_to_world((5.0, 80.0, 10.0)))  # crosshair away from the balls
    axial = window.slice_views["axial"]
    qtbot.waitUntil(lambda: axial.painted, timeout=10_000)
    return axial, volume


def test_zoom_pan_and_one_big_view(qtbot, window, small_ct_file):
    open_and_wait(qtbot, window, small_ct_file)
    axial = window.slice_views["axial"]
    size_before = axial.size()
    anchor = QPointF(axial.viewport().center().x() + 40.5, axial.viewport().center().y() - 25.25)
    under = axial.widget_to_world(anchor.x(), anchor.y())
    wheel(axial, anchor, 1, Qt.ControlModifier)  # Ctrl+wheel zooms about the pointer
    assert axial.zoom == pytest.approx(1.25)
    np.testing.assert_allclose(axial.widget_to_world(anchor.x(), anchor.y()), under, atol=1e-9)
    drag(axial, anchor, QPointF(anchor.x() + 30, anchor.y() + 20), button=Qt.MiddleButton)  # pan
    moved = axial.world_to_widget(under)
    assert (moved.x(), moved.y()) == (pytest.approx(anchor.x() + 30), pytest.approx(anchor.y() + 20))
    # The slice views are large beside the 3D views, not strips under them.
    assert axial.height() > 200 and axial.width() > 200 and axial.isVisible() and window.views[0].isVisible()

    mouse(axial, "double", axial.viewport().center())  # one big view
    qtbot.waitUntil(lambda: axial.width() > size_before.width() * 1.5, timeout=10_000)
    assert window.enlarged is axial and not window.views[0].isVisible()
    assert not window.slice_views["coronal"].isVisible()
    mouse(axial, "double", axial.viewport().center())  # and back
    qtbot.waitUntil(lambda: window.views[0].isVisible(), timeout=10_000)
    assert window.enlarged is None and window.slice_views["coronal"].isVisible()

    view = window.views[1]
    view.enlarge_button.click()  # a 3D view alone
    assert window.enlarged is view and not window.views[0].isVisible() and not axial.isVisible()
    wait_ready(qtbot, window)
    view.enlarge_button.click()
    assert all(v.isVisible() for v in window.views[:4]) and axial.isVisible()


def test_crosshair_moved_in_a_slice_view_moves_the_planes_in_3d(qtbot, window, small_ct_file):
    open_and_wait(qtbot, window, small_ct_file)
    axial = window.slice_views["axial"]
    volume = window.model.base_volume
    target = volume.index_to_world((30.0, 90.0, 27.0))
    qtbot.waitUntil(lambda: axial.painted, timeout=10_000)
    spot = axial.world_to_widget(target)
    mouse(axial, "press", spot)
    mouse(axial, "release", spot)
    np.testing.assert_allclose(window.model.cursor[:2], target[:2], atol=1e-6)
    for view in window.views[: window.model.view_count]:
        coronal, sagittal = view.plane_outline_points("coronal"), view.plane_outline_points("sagittal")
        assert len(coronal) == 4 and len(sagittal) == 4
        np.testing.assert_allclose(coronal[:, 1], target[1], atol=1e-6)  # the coronal plane went to y
        np.testing.assert_allclose(sagittal[:, 0], target[0], atol=1e-6)  # the sagittal plane went to x
    # The wheel in the coronal view moves the coronal plane by one slice in 3D too.
    coronal_view = window.slice_views["coronal"]
    wheel(coronal_view, coronal_view.viewport().center(), 1)
    step = volume.spacing[1]
    assert abs(window.views[0].plane_outline_points("coronal")[0, 1] - target[1]) == pytest.approx(step)


def test_oblique_reformat_by_rotating_the_crosshair(qtbot, window, tmp_path):
    from app.io import save_volume
    from app.volume import Volume

    ramp = Volume(np.zeros((30, 48, 40), np.float32), spacing=(1.0, 1.0, 1.5), origin=(-20.0, -24.0, 0.0))
    k, j, i = np.mgrid[0:30, 0:48, 0:40]
    world = ramp.index_to_world(np.stack([i, j, k], axis=-1))
    ramp.array = (100 + 2 * world[..., 0] - 3 * world[..., 1] + world[..., 2]).astype(np.float32)
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-cpu")
    open_and_wait(qtbot, window, save_volume(ramp, tmp_path / "ramp.nii.gz"))
    axial = window.slice_views["axial"]
    qtbot.waitUntil(lambda: axial.painted, timeout=10_000)
    centre = axial.world_to_widget(window.model.cursor)
    radius = 60.0
    start = QPointF(centre.x() + radius, centre.y())
    # Ctrl+drag along an arc to 30 degrees counter-clockwise on screen (y grows downwards).
    mouse(axial, "press", start, modifiers=Qt.ControlModifier)
    for angle in np.linspace(0, 30, 16)[1:]:
        a = np.radians(angle)
        mouse(axial, "move", QPointF(centre.x() + radius * np.cos(a), centre.y() - radius * np.sin(a)),
              buttons=Qt.LeftButton, modifiers=Qt.ControlModifier)
    mouse(axial, "release", QPointF(centre.x() + radius * np.cos(np.radians(30)),
                                    centre.y() - radius * np.sin(np.radians(30))), modifiers=Qt.ControlModifier)
    coronal = window.slice_views["coronal"]
    tilt = np.degrees(np.arccos(abs(coronal.frame.n @ np.array([0.0, 1.0, 0.0]))))
    assert tilt == pytest.approx(30.0, abs=0.6)
    assert coronal.frame.oblique and not axial.frame.oblique
    # The coronal view shows the volume reformatted on the tilted plane: the affine field, exactly.
    grid = coronal.grid
    values = coronal._pixels
    points = grid.points()
    index = ramp.world_to_index(points)
    inside = np.all((index >= 0) & (index <= np.asarray(ramp.dimensions) - 1), axis=-1)
    expected = 100 + 2 * points[..., 0] - 3 * points[..., 1] + points[..., 2]
    assert inside.sum() > 500
    np.testing.assert_allclose(values[inside], expected[inside], atol=2e-3)
    # ... and the 3D views draw the tilted coronal plane.
    outline = window.views[0].plane_outline_points("coronal")
    np.testing.assert_allclose((outline - window.model.cursor) @ coronal.frame.n, 0.0, atol=1e-6)
    window.undo_action.trigger()  # the rotation is undoable
    assert not coronal.frame.oblique


def test_distance_and_angle_on_known_geometry(qtbot, window, tmp_path):
    axial, volume = _open_markers(qtbot, window, tmp_path)
    blobs = _match(_blob_centres(axial, 3), axial)
    world = {name: volume.index_to_world(ijk) for name, ijk in MARKERS.items()}
    window.set_tool("distance")
    drag(axial, QPointF(*blobs["a"]), QPointF(*blobs["b"]))
    distance = window.model.measurements[0]
    assert distance.kind == "distance" and distance.results["unit"] == "mm"
    assert distance.results["value"] == pytest.approx(np.linalg.norm(world["b"] - world["a"]), abs=0.1)

    window.set_tool("angle")
    for name in ("a", "vertex", "b"):
        mouse(axial, "press", QPointF(*blobs[name]))
        mouse(axial, "release", QPointF(*blobs[name]))
    angle = window.model.measurements[1]
    u, v = world["a"] - world["vertex"], world["b"] - world["vertex"]
    expected = np.degrees(np.arccos(u @ v / np.linalg.norm(u) / np.linalg.norm(v)))
    assert angle.kind == "angle" and angle.results["value"] == pytest.approx(expected, abs=0.1)
    table = window.measurements_panel.table
    assert table.rowCount() == 2 and "mm" in table.item(0, 1).text() and "degrees" in table.item(1, 1).text()
    window.undo_action.trigger()
    assert len(window.model.measurements) == 1 and table.rowCount() == 1
    window.redo_action.trigger()
    assert len(window.model.measurements) == 2


def test_ellipse_statistics_against_numpy(qtbot, window, tmp_path):
    axial, volume = _open_markers(qtbot, window, tmp_path)
    corner0 = volume.index_to_world((40.0, 20.0, 10.0))
    corner1 = volume.index_to_world((66.0, 44.0, 10.0))
    window.set_tool("ellipse")
    drag(axial, axial.world_to_widget(corner0), axial.world_to_widget(corner1))
    result = window.model.measurements[0].results
    centre, radii = (corner0 + corner1) / 2, np.abs(corner1 - corner0)[:2] / 2
    ny, nx = volume.array.shape[1:]
    j, i = np.mgrid[0:ny, 0:nx]
    xy = volume.index_to_world(np.stack([i, j, np.full_like(i, 10)], axis=-1))[..., :2]
    inside = (((xy - centre[:2]) / radii) ** 2).sum(axis=-1) <= 1.0
    values = volume.array[10][inside].astype(np.float64)
    assert result["pixels"] == values.size
    assert result["mean"] == pytest.approx(values.mean(), rel=1e-6)
    assert result["sd"] == pytest.approx(values.std(), rel=1e-5)
    assert result["min"] == pytest.approx(values.min()) and result["max"] == pytest.approx(values.max()) == 1000.0
    assert result["value"] == pytest.approx(values.size * 0.25) and result["unit"] == "mm^2"


def test_label_map_colours_and_names_on_hover(qtbot, window, tmp_path):
    from app.io import save_volume
    from app.volume import Volume

    base = marker_volume()
    labels = np.zeros(base.array.shape, np.uint8)
    labels[:, 10:40, 10:35] = 3
    labels[:, 50:80, 40:70] = 7
    atlas = save_volume(Volume(labels, spacing=base.spacing, origin=base.origin), tmp_path / "atlas.nii.gz")
    (tmp_path / "atlas.label").write_text('    3   255    0    0        1  1  1    "Left thing"\n'
                                          '    7     0    0  255        1  1  1    "Right thing"\n')
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-cpu")
    open_and_wait(qtbot, window, marker_file(tmp_path))
    with qtbot.waitSignal(window.volume_loaded, timeout=60_000):
        window.open_path(atlas)  # detected as labels, drawn over the volume on show
    assert window.model.label_items and window.model.base_volume.dimensions == base.dimensions
    axial = window.slice_views["axial"]
    qtbot.waitUntil(lambda: len(axial.overlays) == 1, timeout=30_000)
    assert axial.overlays[0][1] == "labels" and axial.overlays[0][2].name(3) == "Left thing"
    window.model.set_label_opacity(1.0)
    point = base.index_to_world((20.0, 25.0, 10.0))
    column, row = axial.grid.pixel_of(*axial.grid.to_plane(point))
    assert tuple(axial._buffer[int(round(row)), int(round(column))]) == (255, 0, 0)  # label 3 in its colour
    spot = axial.world_to_widget(point)
    mouse(axial, "move", spot, buttons=Qt.NoButton)
    assert "label 3 Left thing" in axial._hover
    mouse(axial, "move", axial.world_to_widget(base.index_to_world((55.0, 65.0, 10.0))), buttons=Qt.NoButton)
    assert "label 7 Right thing" in axial._hover
    from qtpy.QtCore import QEvent
    from qtpy.QtWidgets import QApplication

    QApplication.sendEvent(axial, QEvent(QEvent.Leave))
    assert axial._hover == ""  # the read-out is cleared when the pointer leaves


def test_nearest_interpolation_option(qtbot, window, small_ct_file):
    open_and_wait(qtbot, window, small_ct_file)
    axial = window.slice_views["axial"]
    volume = window.model.base_volume
    window.model.set_cursor(volume.index_to_world((64.0, 64.0, 20.4)))  # between two slices
    linear = axial._pixels.copy()
    window.controls.interpolation_box.setCurrentIndex(window.controls.interpolation_box.findData("nearest"))
    window.controls.interpolation_box.activated.emit(window.controls.interpolation_box.currentIndex())
    assert window.model.interpolation == "nearest"
    reference = sample_plane(volume, plane_grid(volume, plane_frame("axial"), window.model.cursor), order=0)
    np.testing.assert_array_equal(axial._pixels, reference)
    assert not np.array_equal(axial._pixels, linear)
