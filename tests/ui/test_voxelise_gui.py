"""Voxelising a mesh in the window: open a volume and a mesh, run the "voxelise" operation (directly and through its
dialog), see the mask in two render modes and drawn over the slice views."""

from __future__ import annotations

import numpy as np
from qtpy.QtCore import QTimer
from qtpy.QtWidgets import QApplication, QDialog

from .conftest import open_and_wait, wait_ready


def _ring_file(tmp_path, centre):
    """A closed torus (ring radius 40 mm, tube 14 mm) around ``centre``, written as binary STL."""
    from vtkmodules.vtkIOGeometry import vtkSTLWriter

    from algorithms.common.vtk_bridge import polydata_from_arrays
    from tests.algorithms.fields._voxelise_shapes import torus

    points, triangles = torus(40.0, 14.0, around=96, across=48, centre=centre)
    path = tmp_path / "ring.stl"
    writer = vtkSTLWriter()
    writer.SetFileTypeToBinary()
    writer.SetFileName(str(path))
    writer.SetInputData(polydata_from_arrays(points, triangles))
    writer.Write()
    return path, points, triangles


def test_voxelise_a_mesh_in_the_window(qtbot, window, small_ct_file, tmp_path):
    from algorithms.fields.voxelise import voxelise

    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "voxel-faces")
    window.model.set_view_mode(1, "marching-cubes")
    open_and_wait(qtbot, window, small_ct_file)
    head = window.model.item
    shown = window.views[:2]  # the layout's two views
    before = [view.capture().copy() for view in shown]
    path, points, triangles = _ring_file(tmp_path, head.volume.centre)
    with qtbot.waitSignal(window.volume_loaded, timeout=60_000):
        window.open_path(path)
    mesh = window.model.scene.first("mesh")
    assert mesh is not None and mesh.name == "ring.stl"

    # Directly, on the volume's grid.
    with qtbot.waitSignal(window.operation_finished, timeout=120_000) as made:
        window.run_operation("voxelise", items={"mesh": mesh, "like": head}, options={"inside": "parity"})
    mask = made.args[0]
    assert mask.kind == "field" and mask.role == "mask" and mask.volume.grid.same_as(head.volume.grid)
    expected = voxelise(points, triangles, head.volume.grid)
    assert np.array_equal(mask.volume.array, expected) and expected.sum() > 1000
    assert mask.metadata["voxelise"]["rule"] == "parity"

    # Shown in both views: voxel faces and marching cubes of the mask, a ring where the head was.
    wait_ready(qtbot, window)
    assert window.model.item is mask
    for view, old in zip(shown, before):
        assert view.item is mask
        image = view.capture()
        assert image.std() > 0 and np.count_nonzero(np.any(image != old, axis=-1)) > 0.01 * image[..., 0].size
        assert view.current_surface().stats["triangles"] > 1000
    # ... and drawn over the slices of the head.
    axial = window.slice_views["axial"]
    qtbot.waitUntil(lambda: any(entry[1] == "mask" for entry in axial.overlays), timeout=30_000)

    # Through the Operations dialog: no 'like' volume, 48 voxels along the ring's longest side, winding rule.
    def answer():
        dialog = QApplication.activeModalWidget()
        if not isinstance(dialog, QDialog) or dialog.objectName() != "operation-voxelise":
            QTimer.singleShot(50, answer)
            return
        dialog.inputs["mesh"].setCurrentIndex(dialog.inputs["mesh"].findData(mesh.name))
        dialog.inputs["like"].setCurrentIndex(dialog.inputs["like"].findData(None))
        dialog.options_panel.widgets["grid"].setValue(48)
        inside = dialog.options_panel.widgets["inside"]
        inside.setCurrentIndex(inside.findData("winding"))
        dialog.ok_button.click()

    QTimer.singleShot(50, answer)
    with qtbot.waitSignal(window.operation_finished, timeout=120_000) as made:
        window.run_operation("voxelise")
    coarse = made.args[0]
    assert coarse.volume.dimensions[0] == 48 + 2 * 2  # 48 along the ring's longest side (x), padding 2
    assert coarse.metadata["voxelise"]["rule"] == "winding"
    assert coarse.name != mask.name and coarse.volume.array.sum() > 100
