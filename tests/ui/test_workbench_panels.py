"""Issue 18 in the real window: undo/redo of a transfer-function drag, a session saved and reopened in a new window
(same layout, camera, measurements and picture), the provenance panel of a damaged DICOM folder, the series
chooser, and the View menu's dock entries with Reset layout."""

from __future__ import annotations

import numpy as np
import pytest
from qtpy.QtCore import QPoint, Qt
from qtpy.QtTest import QTest

from algorithms.compare.image_metrics import psnr
from app.measurements import Measurement

from .conftest import open_and_wait, wait_ready


def test_undo_and_redo_of_a_transfer_function_drag(qtbot, window, small_ct_file):
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-cpu")
    open_and_wait(qtbot, window, small_ct_file)
    original = window.model.transfer_function
    before = window.views[0].capture()
    curve = window.controls.curve
    start = curve._to_screen(*curve.opacity_points[2])
    end = QPoint(int(start.x()), int(curve._plot().bottom()))
    QTest.mousePress(curve, Qt.LeftButton, Qt.NoModifier, start.toPoint())
    QTest.mouseMove(curve, end)
    QTest.mouseRelease(curve, Qt.LeftButton, Qt.NoModifier, end)
    dragged = window.model.transfer_function
    assert dragged != original and window.undo_stack.count() == 1
    wait_ready(qtbot, window)
    after = window.views[0].capture()
    assert after.mean() < before.mean()

    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5_000)
    assert window.undo_action.shortcut().toString() == "Ctrl+Z"
    QTest.keyClick(window, Qt.Key_Z, Qt.ControlModifier)  # Ctrl+Z
    assert window.model.transfer_function == original
    assert [tuple(p) for p in curve.opacity_points] == list(original.opacity_points)  # the editor follows
    wait_ready(qtbot, window)
    assert psnr(window.views[0].capture(), before) > 40  # the picture is back
    window.redo_action.trigger()
    assert window.model.transfer_function == dragged
    wait_ready(qtbot, window)
    assert psnr(window.views[0].capture(), after) > 40
    window.model.set_iso(500.0)
    window.model.set_preset("ct-skin")
    assert window.undo_stack.count() == 3
    window.undo_action.trigger()
    window.undo_action.trigger()
    assert window.model.iso == 300.0 and window.model.preset == "ct-bone"


def test_session_saved_and_reopened_after_a_restart(qtbot, tmp_path, make_window, small_ct_file):
    from qtpy.QtCore import QSettings

    from ui.lifetime import delete_now

    first = make_window()
    from app.io import save_volume
    from app.scene import FieldItem

    first.model.set_layout("1x2")
    first.model.set_view_mode(0, "flying-edges")
    first.model.set_view_mode(1, "raymarch", {"samples": 96})
    open_and_wait(qtbot, first, small_ct_file)
    head = first.model.base
    # Labels opened from a file, a surface made by an operation, a mask made in memory.
    tissue = (head.volume.array > -300).astype(np.uint8) + (head.volume.array > 300)
    labels_file = save_volume(head.volume.with_array(tissue, units="", modality=""), tmp_path / "tissue.nii.gz")
    with qtbot.waitSignal(first.volume_loaded, timeout=60_000):
        first.open_labels(labels_file)
    with qtbot.waitSignal(first.operation_finished, timeout=120_000):
        first.run_operation("extract-surface", items={"volume": head}, options={"method": "flying-edges"})
    bone = head.volume.with_array((head.volume.array > 300).astype(np.uint8), units="", modality="")
    first.model.scene.add(FieldItem("bone mask", volume=bone, role="mask"))
    names = first.model.scene.names()
    camera = first.views[0].renderer.GetActiveCamera()
    camera.Azimuth(35)
    camera.Elevation(20)
    first.model.set_iso(500.0)
    first.model.rotate_slices("axial", 15.0)
    first.slice_views["coronal"].set_zoom(2.0)
    first.model.add_measurement(Measurement("distance", points=[(0, 0, 0), (30, 40, 0)]))
    first.add_tool("box")
    first.add_tool("sphere")
    first.set_tool_mode(1, "keep")
    first.model.cutaways.replace(1, first.model.cutaways.tools[1].moved(centre=first.model.base_volume.centre,
                                                                        size=(60.0,)))
    first.model.cutaways.set_evaluation("distance")
    tools = list(first.model.cutaways.tools)
    wait_ready(qtbot, first)
    pose = (camera.GetPosition(), camera.GetFocalPoint(), camera.GetViewUp())
    views_before = first.grab_views()
    session = first.save_session(tmp_path / "work.voxelscope.json")
    delete_now(first)  # as the application ends: closed, then deleted

    second = make_window(QSettings(str(tmp_path / "other.ini"), QSettings.IniFormat), size=None)  # a fresh start
    with qtbot.waitSignal(second.session_opened, timeout=120_000):
        assert second.open_session(session)
    wait_ready(qtbot, second)
    assert second.model.layout == "1x2" and second.model.view_modes[:2] == ["flying-edges", "raymarch"]
    assert second.model.view_options[1] == {"samples": 96} and second.views[1].pipeline.options["samples"] == 96
    assert second.model.scene.names() == names and second.model.item.name == head.name
    assert [item.name for item in second.model.label_items] == ["tissue.nii.gz"]
    np.testing.assert_array_equal(second.model.scene.get("bone mask").volume.array, bone.array)
    surface = second.model.scene.of_kind("mesh")[0]
    assert surface.polydata.GetNumberOfPoints() == first.model.scene.get(surface.name).polydata.GetNumberOfPoints()
    assert second.size().width() == 1200 and second.model.iso == 500.0
    restored = second.views[0].renderer.GetActiveCamera()
    for a, b in zip(pose, (restored.GetPosition(), restored.GetFocalPoint(), restored.GetViewUp())):
        np.testing.assert_allclose(a, b, atol=1e-6)
    assert [m.results["value"] for m in second.model.measurements] == [pytest.approx(50.0)]
    assert second.measurements_panel.table.rowCount() == 1
    np.testing.assert_allclose(second.model.slice_rotation, first.model.slice_rotation)
    assert second.slice_views["coronal"].zoom == 2.0
    assert [(t.shape, t.mode) for t in second.model.cutaways.tools] == [("box", "remove"), ("sphere", "keep")]
    assert second.current_tool == 1  # the selected tool keeps its widget
    for before, after in zip(tools, second.model.cutaways.tools):
        np.testing.assert_allclose(after.matrix, before.matrix)
        assert after.size == before.size
    assert second.model.cutaways.evaluation == "distance" and second.tool_panel.list.count() == 2
    assert all(len(view.pipeline.inputs.tools) == 2 for view in second.views[:2])  # the views are cut again
    views_after = second.grab_views()
    assert views_after.shape == views_before.shape
    assert psnr(views_after, views_before) > 35  # the same pictures after the restart
    second.close()


def test_the_default_views_change_only_when_asked(make_window):
    """A run that picks its own modes (``voxelscope gui --modes``, a session) leaves the next start's layout and
    modes alone; View > Use these views as the default changes them."""
    from app.workbench import DEFAULT_MODES

    def start():
        return make_window(show=False, size=None)

    first = start()
    first.model.set_layout("1x2")
    first.model.set_view_mode(0, "raymarch")
    first.model.set_view_mode(1, "shear-warp")
    first.close()
    second = start()
    assert second.model.layout == "2x2" and tuple(second.model.view_modes) == DEFAULT_MODES
    second.model.set_layout("1x2")
    second.model.set_view_mode(1, "shear-warp")
    second.save_default_views()
    second.close()
    third = start()
    assert third.model.layout == "1x2" and third.model.view_modes[:2] == [DEFAULT_MODES[0], "shear-warp"]
    assert third.views[1].mode_box.currentData() == "shear-warp"
    third.close()


def test_provenance_panel_lists_every_warning_of_a_damaged_folder(qtbot, window, tmp_path):
    from app.io import write_dicom_series

    from ..app.dicom_helpers import small_ct

    volume = small_ct(shape=(14, 40, 36))
    paths = write_dicom_series(volume, tmp_path / "damaged", rescale_intercept=-1024, description="HEAD 3 mm")
    paths[6].unlink()  # a missing slice: filled by interpolation
    paths[0].write_bytes(paths[0].read_bytes()[:-500])  # a truncated file
    (tmp_path / "damaged" / "notes.txt").write_text("scanned on Tuesday")
    window.model.set_layout("1x1")
    open_and_wait(qtbot, window, tmp_path / "damaged")
    warnings = window.model.base_volume.metadata["warnings"]
    assert len(warnings) >= 3
    text = window.provenance_panel.text()
    for warning in warnings:
        assert warning in text
    assert "invented by linear interpolation" in text.splitlines()[0]  # first, as an alert
    assert "VOXELSCOPE-0001" in text and "HEAD 3 mm" in text and "Interpolated slices" in text
    assert window.provenance_dock.isVisible()
    qtbot.wait(16_000)  # unlike the status bar, the panel keeps them
    assert all(warning in window.provenance_panel.text() for warning in warnings)
    assert window.other_series_action.isEnabled()


def test_series_chooser_greys_out_what_cannot_be_opened(qtbot):
    from app.provenance import series_choices
    from ui.dialogs import SeriesChooser

    series = series_choices([
        {"series_uid": "1.1", "description": "scout", "modality": "CT", "slices": 1, "rows": 512, "columns": 512},
        {"series_uid": "1.2", "description": "head", "modality": "CT", "slices": 120, "rows": 512, "columns": 512},
    ])
    dialog = SeriesChooser("/data", series)
    qtbot.addWidget(dialog)
    scout = dialog.list.item(0)
    assert not scout.flags() & Qt.ItemIsEnabled and "cannot be opened" in scout.text()
    assert dialog.chosen_uid() == "1.2"


def test_view_menu_brings_back_closed_docks_and_resets_the_layout(qtbot, window, tmp_path):
    view_menu = next(a.menu() for a in window.menuBar().actions() if a.text() == "&View")
    texts = [a.text() for a in view_menu.actions()]
    for title in ("Controls", "Scene", "Measurements", "Provenance", "Tools", "Reset &layout"):
        assert title in texts
    window.control_dock.close()
    assert not window.control_dock.isVisible()
    next(a for a in view_menu.actions() if a.text() == "Controls").trigger()
    assert window.control_dock.isVisible()
    window.provenance_dock.setFloating(True)
    window.scene_dock.close()
    next(a for a in view_menu.actions() if a.text() == "Reset &layout").trigger()
    assert window.scene_dock.isVisible() and not window.provenance_dock.isFloating()
    # "Open another series" only for DICOM folders
    from app.io import save_volume

    from ..app.dicom_helpers import small_ct

    open_and_wait(qtbot, window, save_volume(small_ct(), tmp_path / "ct.nii.gz"))
    assert not window.other_series_action.isEnabled()


def test_mr_data_get_mr_presets_and_an_automatic_window(qtbot, window):
    from app.samples import sample_path

    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "flying-edges")
    open_and_wait(qtbot, window, sample_path("mri"))
    box = window.controls.preset_box
    suitable = [box.itemData(i) for i in range(box.count()) if box.itemData(i)
                and not box.itemData(i, Qt.UserRole + 1)]
    assert "ct-bone" not in suitable and "mr-default" in suitable
    presets = [window.controls.window_presets.itemText(i) for i in range(window.controls.window_presets.count())]
    assert any(text.startswith("Automatic") for text in presets) and not any("Bone" in t for t in presets)
    forced = next(i for i in range(box.count()) if box.itemData(i) == "ct-bone")
    box.setCurrentIndex(forced)
    box.activated.emit(forced)
    assert window.model.preset == "ct-bone" and window.controls.preset_warning.isVisibleTo(window.controls)
    assert "CT" in window.statusBar().currentMessage()
