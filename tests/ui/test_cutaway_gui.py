"""Cut-away tools in the window (issue 15): a box tool added from the tool list, dragged with the mouse in one 3D
view, cuts all four linked views; switched to keep, it is the ROI crop, exported and reopened with the right
geometry."""

from __future__ import annotations

import numpy as np
from qtpy.QtCore import QPointF, Qt
from qtpy.QtWidgets import QFileDialog

from .conftest import open_and_wait
from .gui_helpers import drag


def _captures(window):
    return [view.capture().astype(np.int16) for view in window.views[: window.model.view_count]]


def _wait_all(qtbot, window, action, timeout=180_000):
    with qtbot.waitSignal(window.all_views_ready, timeout=timeout):
        action()
    qtbot.waitUntil(window.fully_ready, timeout=timeout)


def _widget_point(view, world):
    """Widget pixels (Qt, origin top left) of the LPS point ``world`` in ``view``."""
    renderer = view.renderer
    renderer.SetWorldPoint(*map(float, world), 1.0)
    renderer.WorldToDisplay()
    x, y, _ = renderer.GetDisplayPoint()
    ratio = view.plotter.interactor.devicePixelRatioF()
    height = view.plotter.ren_win.GetSize()[1]
    return QPointF(x / ratio, (height - 1 - y) / ratio)


def test_box_tool_dragged_in_one_view_cuts_all_four_then_keep_exports_the_crop(qtbot, window, small_ct_file,
                                                                               tmp_path, monkeypatch):
    from app.io import load_volume

    window.model.set_layout("2x2")
    open_and_wait(qtbot, window, small_ct_file)
    assert window.model.view_count == 4
    uncut = _captures(window)

    _wait_all(qtbot, window, lambda: qtbot.mouseClick(window.tool_panel.add_buttons["box"], Qt.LeftButton))
    assert [tool.shape for tool in window.model.cutaways.tools] == ["box"]
    assert window.tool_panel.list.count() == 1
    start_centre = window.model.cutaways.tools[0].centre.copy()
    assert all(widget.enabled for widget in window.tool_widgets[:4])

    # Drag the box with the middle button (VTK's box widget: translate) in the first view, left and up.
    view = window.views[0]
    start = _widget_point(view, start_centre)
    end = QPointF(start.x() - 25.0, start.y() - 20.0)
    _wait_all(qtbot, window, lambda: drag(view.plotter.interactor, start, end, button=Qt.MiddleButton,
                                                  steps=10))
    moved = window.model.cutaways.tools[0]
    assert np.linalg.norm(moved.centre - start_centre) > 5.0, "the drag did not move the tool"
    # Every linked view's widget shows the moved tool, and every view shows the cut.
    for widget in window.tool_widgets[:4]:
        assert np.allclose(widget.current_tool().centre, moved.centre, atol=1e-6)
    for view in window.views[:4]:
        assert view.pipeline.inputs.tools == (moved,)
    cut = _captures(window)
    for index, (before, after) in enumerate(zip(uncut, cut)):
        changed = (np.abs(before - after).max(axis=-1) > 30).mean()
        assert changed > 0.005, f"view {index} ({window.views[index].mode}) does not show the cut"

    # A mesh export of a surface view extracts from the volume minus the tool (capped at the cut).
    from app.cutaways import removed_overlay

    source = window.export_source(window.views[0])
    removed = removed_overlay(window.model.volume, [moved]).array.astype(bool)
    assert removed.any() and np.all(source.array[removed] < window.views[0].pipeline.inputs.iso)
    assert np.array_equal(source.array[~removed] >= window.views[0].pipeline.inputs.iso,
                          window.model.volume.array[~removed] >= window.views[0].pipeline.inputs.iso)

    # The slice views shade the removed region (a mask overlay on their volume's grid, computed in a worker).
    slices = list(window.slice_views.values())
    qtbot.waitUntil(lambda: all(any(o[1] == "mask" for o in v.overlays) for v in slices), timeout=60_000)
    shaded = next(o[0] for o in slices[0].overlays if o[1] == "mask")
    assert shaded.dimensions == window.model.base_volume.dimensions and 0 < shaded.array.mean() < 0.5

    # Keep mode: the region of interest.
    _wait_all(qtbot, window, lambda: window.set_tool_mode(0, "keep"))
    assert window.model.cutaways.tools[0].mode == "keep"
    kept = _captures(window)
    for index, (removed, keep) in enumerate(zip(cut, kept)):
        assert (np.abs(removed - keep).max(axis=-1) > 30).mean() > 0.005, index

    # File > Export cropped volume writes the inside of the box on the volume's grid (in a worker); reopened, it sits
    # there.
    path = tmp_path / "roi.nii.gz"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(path), ""))
    window.export_cropped_volume_dialog()
    qtbot.waitUntil(path.exists, timeout=60_000)
    original, cropped = window.model.volume, load_volume(path)
    assert np.allclose(cropped.spacing, original.spacing)
    assert np.allclose(cropped.direction, original.direction)
    box = np.asarray(moved.world_bounds())  # the region: the box, within the volume's voxel centres
    inside = np.asarray(original.world_bounds)
    box[0::2], box[1::2] = np.maximum(box[0::2], inside[0::2]), np.minimum(box[1::2], inside[1::2])
    low, high = np.asarray(cropped.world_bounds[0::2]), np.asarray(cropped.world_bounds[1::2])
    spacing = np.asarray(original.spacing)
    assert np.all(low >= box[0::2] - 1e-6) and np.all(high <= box[1::2] + 1e-6)
    assert np.all(low <= box[0::2] + spacing + 1e-6) and np.all(high >= box[1::2] - spacing - 1e-6)
    offset = np.rint((np.asarray(cropped.origin) - np.asarray(original.origin)) / spacing).astype(int)
    nx, ny, nz = cropped.dimensions
    block = original.array[offset[2]:offset[2] + nz, offset[1]:offset[1] + ny, offset[0]:offset[0] + nx]
    np.testing.assert_array_equal(cropped.array, block)
    window.open_path(path)
    qtbot.waitUntil(lambda: window.model.volume is not None and window.model.volume.dimensions == cropped.dimensions,
                    timeout=120_000)
    assert np.allclose(window.model.volume.origin, cropped.origin)


def test_gui_cut_flags_start_every_view_cut_and_bad_specs_get_one_line(qtbot, settings, small_ct_file, tmp_path):
    import subprocess
    import sys

    bad = subprocess.run([sys.executable, "-m", "app.cli", "gui", "--cut", "box:1,2,3", "--exit"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "expected box:X,Y,Z,SX,SY,SZ" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1
    from app.pipeline import read_png

    shots = []
    for cut in (["--cut", "sphere:-30,-60,30,50", "--cut-eval", "distance"], []):
        shot = tmp_path / f"cut{len(cut)}.png"
        done = subprocess.run([sys.executable, "-m", "app.cli", "gui", str(small_ct_file), *cut, "--layout", "1x2",
                               "--modes", "flying-edges,raymarch", "--screenshot", shot, "--exit"],
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        shots.append(read_png(shot).astype(np.int16))
    assert shots[0].shape == shots[1].shape
    assert (np.abs(shots[0] - shots[1]).max(axis=-1) > 30).mean() > 0.002, "the --cut window looks uncut"
