"""CSG in the window: load two meshes, subtract one from the other with the "csg" operation, drag the isovalue
slider (the offset in mm for a distance field: the surface grows), and export the result through File > Export
mesh."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from qtpy.QtWidgets import QFileDialog

from app.mesh_cleanup import Cleanup

from .conftest import open_and_wait, wait_ready


def _stl(path, points, triangles):
    from vtkmodules.vtkIOGeometry import vtkSTLWriter

    from algorithms.common.vtk_bridge import polydata_from_arrays

    writer = vtkSTLWriter()
    writer.SetFileTypeToBinary()
    writer.SetFileName(str(path))
    writer.SetInputData(polydata_from_arrays(points, triangles))
    writer.Write()
    return path


def test_subtract_offset_and_export(qtbot, window, small_ct_file, tmp_path, monkeypatch):
    from vtkmodules.vtkIOGeometry import vtkSTLReader

    from algorithms.compare.topology import edge_manifoldness
    from algorithms.common.vtk_bridge import polydata_arrays
    from tests.algorithms.fields._voxelise_shapes import sphere, torus
    from ui.dialogs import ExportOptionsDialog

    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "marching-cubes")
    open_and_wait(qtbot, window, small_ct_file)
    centre = np.asarray(window.model.item.volume.centre)
    ring = _stl(tmp_path / "ring.stl", *torus(40.0, 14.0, around=96, across=48, centre=centre))
    ball = _stl(tmp_path / "ball.stl", *sphere(20.0, around=64, across=32, centre=centre + [40.0, 0.0, 0.0]))
    for path in (ring, ball):
        with qtbot.waitSignal(window.volume_loaded, timeout=60_000):
            window.open_path(path)
    meshes = [item for item in window.model.scene if item.kind == "mesh"]
    assert [m.name for m in meshes] == ["ring.stl", "ball.stl"]

    with qtbot.waitSignal(window.operation_finished, timeout=180_000) as made:
        window.run_operation("csg", items={"a": meshes[0], "b": meshes[1]},
                         options={"operation": "difference", "grid": 64, "band": "6"})
    result = made.args[0]
    assert result.kind == "field" and result.role == "distance"
    assert result.name == "ring.stl - ball.stl"
    wait_ready(qtbot, window)
    assert window.model.item is result
    view = window.views[0]
    triangles_at_zero = view.current_surface().stats["triangles"]
    assert triangles_at_zero > 1000

    # The isovalue slider is the offset in mm: a step up grows the surface outwards.
    slider = window.controls.iso_slider
    low, high = result.volume.value_range
    step = int(round((3.0 - low) / (high - low) * slider.maximum()))
    slider.setValue(step)
    qtbot.waitUntil(lambda: window.model.iso > 2.0, timeout=10_000)
    wait_ready(qtbot, window)
    offset = window.model.iso
    assert 2.0 < offset < 4.0
    assert view.current_surface().stats["triangles"] > triangles_at_zero  # a larger surface at +offset mm

    out = tmp_path / "ring_minus_ball.stl"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args, **kwargs: (str(out), "STL (*.stl)"))
    monkeypatch.setattr(ExportOptionsDialog, "ask", classmethod(lambda cls, path, parent=None: {
        "coordinates": "LPS", "cleanup": Cleanup()}))
    with qtbot.waitSignal(window.tasks.ended, timeout=60_000, check_params_cb=lambda t: "Exporting" in t.label):
        window.export_mesh()
    reader = vtkSTLReader()
    reader.SetFileName(str(out))
    reader.Update()
    points, triangles = polydata_arrays(reader.GetOutput())
    assert len(triangles) > 1000
    assert edge_manifoldness(points, triangles).boundary_edges == 0
    # the exported surface is the +offset surface of ring minus ball, in patient mm: its outer radius about the
    # ring's centre is the torus' 54 mm plus the offset
    radial = np.hypot(points[:, 0] - centre[0], points[:, 1] - centre[1])
    assert abs(radial.max() - (54.0 + offset)) < 1.5
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert sidecar["iso_value"] == offset and sidecar["value_units"] == "mm"
