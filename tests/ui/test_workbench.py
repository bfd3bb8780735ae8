"""The real workbench under a virtual X server: modes, linked cameras, isovalue, errors, export, screenshots."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from qtpy.QtCore import QTimer
from qtpy.QtWidgets import QApplication, QFileDialog, QMessageBox

from algorithms.compare.image_metrics import psnr
from app.mesh_cleanup import Cleanup
from app.pipeline import read_png, write_png
from app.samples import sample_path

from .conftest import open_and_wait, wait_ready

BASELINES = Path(__file__).parent / "baselines"


def test_opens_the_sample_in_four_modes(qtbot, window):
    window.model.set_layout("2x2")
    for index, mode in enumerate(("flying-edges", "vtk-marching-cubes", "vtk-gpu", "vtk-cpu")):
        window.model.set_view_mode(index, mode)
    open_and_wait(qtbot, window, sample_path("ct"))
    assert window.model.volume.dimensions == (512, 512, 176)
    assert [view.mode for view in window.views] == ["flying-edges", "vtk-marching-cubes", "vtk-gpu", "vtk-cpu"]
    for view in window.views:
        image = view.capture()
        assert image.mean() > 3, f"{view.mode} drew nothing"
        assert "frame" in view.stats_label.text()
    # Surface statistics are on show; volume views state their sample step.
    assert "triangles" in window.views[0].stats_label.text()
    assert "sample step 0.27 mm" in window.views[2].stats_label.text()
    # The slice views show the cursor at the volume centre with HU window/level.
    assert window.slice_views["axial"]._slice == 88


def test_switch_modes_in_each_view(qtbot, window, small_ct_file):
    open_and_wait(qtbot, window, small_ct_file)
    for index, mode in enumerate(("vtk-cpu", "flying-edges", "vtk-marching-cubes", "vtk-gpu")):
        view = window.views[index]
        position = view.mode_box.findData(mode)
        view.mode_box.setCurrentIndex(position)
        view.mode_box.activated.emit(position)  # what a user's choice in the combo box emits
        assert window.model.view_modes[index] == mode
        wait_ready(qtbot, window)
        assert view.mode == mode and view.capture().mean() > 3


def _pose(view):
    camera = view.renderer.GetActiveCamera()
    return np.array(camera.GetPosition() + camera.GetFocalPoint() + camera.GetViewUp())


def test_linked_cameras_follow_and_unlink(qtbot, window, small_ct_file):
    open_and_wait(qtbot, window, small_ct_file)
    first, others = window.views[0], window.views[1:]
    # Drag-rotate the first view with the interactor's own camera calls.
    first.renderer.GetActiveCamera().Azimuth(40)
    first.renderer.GetActiveCamera().Elevation(15)
    first.render()
    for view in others:
        np.testing.assert_allclose(_pose(view), _pose(first))
    wait_ready(qtbot, window)
    # The other views redrew for the new pose: their frames changed from the anterior view.
    window.model.set_cameras_linked(False)
    before = [_pose(view) for view in others]
    first.renderer.GetActiveCamera().Azimuth(60)
    first.render()
    for view, pose in zip(others, before):
        np.testing.assert_allclose(_pose(view), pose)
    assert not np.allclose(_pose(first), before[0])
    window.model.set_cameras_linked(True)
    for view in others:
        np.testing.assert_allclose(_pose(view), _pose(first))


def test_isovalue_changes_the_surface(qtbot, window, small_ct_file):
    open_and_wait(qtbot, window, small_ct_file)
    surface_view = window.views[0]
    assert surface_view.mode == "flying-edges"
    bone = surface_view.current_surface().stats["triangles"]
    window.model.set_iso(-300.0)  # skin
    wait_ready(qtbot, window)
    skin = surface_view.current_surface().stats["triangles"]
    assert skin != bone
    assert f"{skin:,} triangles" in surface_view.stats_label.text()
    # Dragging the slider shows a reduced-resolution preview first, the full surface on release.
    window.controls._iso_moved(500.0)
    qtbot.waitUntil(lambda: "preview" in surface_view.stats_label.text(), timeout=60_000)
    window.controls._iso_set(500.0)
    wait_ready(qtbot, window)
    assert "preview" not in surface_view.stats_label.text()
    assert surface_view.current_surface().stats["triangles"] not in (bone, skin)


def test_corrupted_file_shows_a_dialog_and_the_app_survives(qtbot, window, tmp_path, small_ct_file):
    broken = tmp_path / "broken.nii.gz"
    broken.write_bytes(small_ct_file.read_bytes()[:5000])
    with qtbot.waitSignal(window.load_failed, timeout=60_000) as blocker:
        window.open_path(broken)
    assert "broken.nii.gz" in blocker.args[0]
    dialogs = [w for w in QApplication.topLevelWidgets() if isinstance(w, QMessageBox) and w.isVisible()]
    assert dialogs and "broken.nii.gz" in dialogs[0].text()
    dialogs[0].accept()
    open_and_wait(qtbot, window, small_ct_file)
    assert window.model.volume.dimensions == (128, 128, 54)


def test_export_mesh_through_the_menu(qtbot, window, small_ct_file, tmp_path, monkeypatch):
    from vtkmodules.vtkIOGeometry import vtkSTLReader

    from algorithms.compare import surface_arrays
    from app.meshing import to_world

    open_and_wait(qtbot, window, small_ct_file)
    out = tmp_path / "skull.stl"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args, **kwargs: (str(out), "STL (*.stl)"))
    from ui.dialogs import ExportOptionsDialog

    monkeypatch.setattr(ExportOptionsDialog, "ask", classmethod(lambda cls, path, parent=None: {
        "coordinates": "LPS", "cleanup": Cleanup()}))
    surface = window.views[0].current_surface()
    with qtbot.waitSignal(window.tasks.ended, timeout=60_000, check_params_cb=lambda t: "Exporting" in t.label):
        window.export_mesh()
    reader = vtkSTLReader()
    reader.SetFileName(str(out))
    reader.MergingOff()  # keep every written triangle, including zero-area ones at isovalues equal to voxel values
    reader.Update()
    read = reader.GetOutput()
    # Every triangle of the view's surface with an area is in the file (zero-area ones, where the isovalue equals
    # sample values, are dropped on export).
    points, triangles = surface_arrays(surface.polydata)
    areas = np.linalg.norm(np.cross(points[triangles[:, 1]] - points[triangles[:, 0]],
                                    points[triangles[:, 2]] - points[triangles[:, 0]]), axis=1)
    assert read.GetNumberOfCells() == int((areas > 0).sum())
    expected = to_world(surface.polydata, window.model.volume, "LPS").GetBounds()
    np.testing.assert_allclose(read.GetBounds(), expected, atol=1e-3)
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert sidecar["method"] == "flying-edges" and sidecar["source_file"].endswith("small_ct.nii.gz")
    assert sidecar["counts"]["triangles"] == read.GetNumberOfCells()


def test_export_with_capped_edges_re_extracts_a_closed_surface(qtbot, window, small_ct_file, tmp_path, monkeypatch):
    from ui.dialogs import ExportOptionsDialog

    open_and_wait(qtbot, window, small_ct_file)
    out = tmp_path / "capped.stl"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args, **kwargs: (str(out), "STL (*.stl)"))
    monkeypatch.setattr(ExportOptionsDialog, "ask", classmethod(lambda cls, path, parent=None: {
        "coordinates": "RAS", "cleanup": Cleanup(), "close_edges": True}))
    with qtbot.waitSignal(window.tasks.ended, timeout=60_000, check_params_cb=lambda t: "Exporting" in t.label):
        window.export_mesh()
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert sidecar["parameters"]["close_edges"] is True and sidecar["coordinate_system"] == "RAS"
    assert sidecar["validity"]["watertight"] and sidecar["validity"]["outward_normals"]


def test_a_very_large_surface_asks_before_it_is_written(qtbot, window, small_ct_file, tmp_path, monkeypatch):
    import app.meshing
    from ui.dialogs import ExportOptionsDialog

    open_and_wait(qtbot, window, small_ct_file)
    monkeypatch.setattr(app.meshing, "MAX_TRIANGLES", 1000)  # the sample's skull has tens of thousands
    out = tmp_path / "large.stl"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args, **kwargs: (str(out), "STL (*.stl)"))
    monkeypatch.setattr(ExportOptionsDialog, "ask", classmethod(lambda cls, path, parent=None: {
        "coordinates": "LPS", "cleanup": Cleanup()}))
    questions, answers = [], [QMessageBox.No, QMessageBox.Yes]
    monkeypatch.setattr(QMessageBox, "question", lambda parent, title, text, *a: (questions.append(text),
                                                                                   answers.pop(0))[1])

    def exported():
        with qtbot.waitSignal(window.tasks.ended, timeout=60_000, check_params_cb=lambda t: "Exporting" in t.label):
            window.export_mesh()

    exported()  # declined: nothing written
    assert len(questions) == 1 and "more than the 1,000" in questions[0] and "large.stl" in questions[0]
    assert not out.exists() and not Path(str(out) + ".json").exists()
    ended = []
    window.tasks.ended.connect(lambda task: ended.append(task.label) if "Exporting" in task.label else None)
    window.export_mesh()  # accepted: the export runs again without the limit
    qtbot.waitUntil(lambda: len(ended) == 2, timeout=120_000)
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert len(questions) == 2 and sidecar["counts"]["triangles"] > 1000


def test_export_options_dialog_reports_every_choice(qtbot):
    from ui.dialogs import ExportOptionsDialog

    dialog = ExportOptionsDialog("skull.stl")
    qtbot.addWidget(dialog)
    assert dialog.options() == {"coordinates": "LPS", "cleanup": Cleanup(), "close_edges": False}
    dialog.coordinates.setCurrentIndex(1)
    dialog.smooth.setValue(20)
    dialog.decimate.setValue(0.5)
    dialog.largest.setChecked(True)
    dialog.fill_holes.setValue(4.0)
    dialog.close_edges.setChecked(True)
    assert dialog.options() == {
        "coordinates": "RAS", "close_edges": True,
        "cleanup": Cleanup(smooth_iterations=20, decimate=0.5, largest_component=True, fill_holes_mm=4.0),
    }


def test_view_screenshot_matches_the_baseline(qtbot, window, small_ct_file, tmp_path):
    """The flying-edges view of the small phantom, anterior camera, 1x1 layout at a fixed window size.

    Tolerance: PSNR >= 30 dB against the committed baseline (llvmpipe's rasterisation is deterministic; the margin
    absorbs driver-level differences in line and normal interpolation).
    """
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "flying-edges")
    window.resize(1000, 700)
    open_and_wait(qtbot, window, small_ct_file)
    window.reset_camera("anterior")
    wait_ready(qtbot, window)
    image = window.views[0].capture()
    baseline_path = BASELINES / "flying_edges_small_ct.png"
    write_png(image, tmp_path / "current.png")
    assert baseline_path.exists(), f"no baseline; the current image is at {tmp_path / 'current.png'}"
    baseline = read_png(baseline_path)[..., :3]
    assert baseline.shape == image.shape, (baseline.shape, image.shape)
    assert psnr(image, baseline) >= 30.0


def test_gui_keeps_turning_while_meshing_and_cancel_stops(qtbot, window, tmp_path):
    """A 256^3 volume is meshed in a worker: the GUI thread's event loop keeps running meanwhile (a timer on it fires
    again and again while the extraction is under way), and Cancel abandons the extraction, keeping the surface."""
    from app.datasets import sphere_field
    from app.io import save_volume
    from app.volume import Volume

    field = sphere_field((256, 256, 256), 100.0) + 0.05 * np.random.default_rng(0).standard_normal((256, 256, 256))
    path = save_volume(Volume(field.astype(np.float32)), tmp_path / "big.nii")
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-marching-cubes")
    open_and_wait(qtbot, window, path, timeout=300_000)

    view = window.views[0]
    qtbot.wait(500)  # let the window finish drawing the first surface
    ticks: list[bool] = []
    timer = QTimer()
    timer.setInterval(10)
    timer.timeout.connect(lambda: ticks.append(view.pipeline.preparing))
    timer.start()
    window.model.set_iso(0.5)
    qtbot.waitUntil(lambda: not view.pipeline.preparing, timeout=300_000)
    timer.stop()
    # The timer lives on the GUI thread: it only fires while that thread's event loop runs.
    assert sum(ticks) >= 5, "the GUI thread's event loop did not run while the surface was extracted"
    triangles = view.current_surface().stats["triangles"]

    # Cancel: start a new extraction and press Cancel in the status bar once it is under way. The view says it was
    # cancelled and keeps the previous surface (the new one was never finished or shown).
    window.model.set_iso(-2.0)
    qtbot.waitUntil(lambda: window.task_progress.fraction > 0, timeout=30_000)
    window.cancel_button.click()
    qtbot.waitUntil(lambda: not view.pipeline.preparing, timeout=60_000)
    assert view.stats_label.text().startswith("cancelled")
    assert view.current_surface().stats["triangles"] == triangles


def test_dicom_folder_series_choice(qtbot, window, tmp_path, monkeypatch):
    """A localizer beside the series opens without a question; two real series ask which one to open."""
    from app.io import write_dicom_series
    from ui.dialogs import SeriesChooser

    from ..app.dicom_helpers import small_ct, write_scanner_folder

    volume = small_ct(shape=(12, 40, 36))
    write_scanner_folder(volume, tmp_path / "scout")

    def no_question(*args, **kwargs):
        raise AssertionError("the series chooser should not open for a localizer")

    monkeypatch.setattr(SeriesChooser, "ask", classmethod(no_question))
    open_and_wait(qtbot, window, tmp_path / "scout")
    assert window.model.volume.dimensions == volume.dimensions

    second = small_ct(shape=(10, 30, 30))
    write_dicom_series(volume, tmp_path / "two" / "a", rescale_intercept=-1024, description="first")
    uid = "1.2.826.0.1.3680043.8.498.12121"
    write_dicom_series(second, tmp_path / "two" / "b", rescale_intercept=-1024, description="second", series_uid=uid)
    offered = []

    def choose_second(cls, folder, series, parent=None):
        offered.extend(s["description"] for s in series)
        return uid

    monkeypatch.setattr(SeriesChooser, "ask", classmethod(choose_second))
    open_and_wait(qtbot, window, tmp_path / "two")
    assert offered == ["first", "second"]
    assert window.model.volume.dimensions == second.dimensions
    assert window.model.volume.metadata["series_uid"] == uid


def test_transfer_function_editor_drag_changes_the_volume_views(qtbot, window, small_ct_file):
    from qtpy.QtCore import QPoint, Qt
    from qtpy.QtTest import QTest

    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-cpu")
    open_and_wait(qtbot, window, small_ct_file)
    before = window.views[0].capture()
    curve = window.controls.curve
    index = 2  # the 700 HU point of ct-bone: drag it down to opacity 0
    start = curve._to_screen(*curve.opacity_points[index])
    end = QPoint(int(start.x()), int(curve._plot().bottom()))
    QTest.mousePress(curve, Qt.LeftButton, Qt.NoModifier, start.toPoint())
    QTest.mouseMove(curve, end)
    QTest.mouseRelease(curve, Qt.LeftButton, Qt.NoModifier, end)
    assert window.model.transfer_function.opacity_points[index][1] == pytest.approx(0.0, abs=0.01)
    wait_ready(qtbot, window)
    after = window.views[0].capture()
    assert after.mean() < before.mean()  # less opaque bone, darker picture


def test_parallel_projection_toggle(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "vtk-cpu")
    window.model.set_view_mode(1, "raymarch")
    open_and_wait(qtbot, window, small_ct_file)
    camera = window.views[0].renderer.GetActiveCamera()
    distance, angle = camera.GetDistance(), camera.GetViewAngle()
    window.parallel_action.trigger()
    assert camera.GetParallelProjection() and window.views[1].renderer.GetActiveCamera().GetParallelProjection()
    assert camera.GetParallelScale() == pytest.approx(distance * np.tan(np.radians(angle / 2)))
    wait_ready(qtbot, window)
    window.reset_camera("left")
    assert camera.GetParallelProjection()  # a standard view keeps the projection chosen
    window.parallel_action.trigger()
    assert not camera.GetParallelProjection()
