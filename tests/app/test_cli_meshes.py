"""``voxelscope info`` on meshes: made in code (a closed one and one with holes, in OBJ, STL and PLY) and the real
meshes of the shared data folder."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from .test_cli import voxelscope

SHARED_MESHES = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "meshes"


def _uv_sphere():
    """A closed, outward sphere of radius 10 mm (VTK's sphere source); returns points and triangles."""
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    from algorithms.common.vtk_bridge import polydata_arrays, run_algorithm

    source = vtkSphereSource()
    source.SetRadius(10.0)
    source.SetThetaResolution(24)
    source.SetPhiResolution(16)
    return polydata_arrays(run_algorithm(source))


def _write(points, triangles, path: Path) -> Path:
    from vtkmodules.vtkIOGeometry import vtkOBJWriter, vtkSTLWriter
    from vtkmodules.vtkIOPLY import vtkPLYWriter

    from algorithms.common.vtk_bridge import polydata_from_arrays

    writer = {".obj": vtkOBJWriter, ".stl": vtkSTLWriter, ".ply": vtkPLYWriter}[path.suffix]()
    writer.SetInputData(polydata_from_arrays(points, triangles))
    writer.SetFileName(str(path))
    writer.Write()
    return path


@pytest.mark.parametrize("suffix", [".obj", ".stl", ".ply"])
def test_info_reports_closed_and_open_meshes(tmp_path, suffix):
    points, triangles = _uv_sphere()
    closed = json.loads(voxelscope("info", _write(points, triangles, tmp_path / f"sphere{suffix}"), "--json").stdout)
    assert closed["kind"] == "mesh" and closed["closed"] and closed["boundary_edges"] == 0
    assert closed["triangles"] == len(triangles) and closed["points"] == len(np.unique(triangles))
    assert closed["non_manifold_edges"] == 0 and closed["components"] == 1 and closed["orientation"] == "outward"
    expected = [v for pair in zip(points.min(axis=0), points.max(axis=0)) for v in pair]
    assert closed["bounds"] == pytest.approx(expected, abs=1e-5) and closed["bounds"][4:] == pytest.approx([-10, 10])
    assert closed["volume_mm3"] == pytest.approx(4 / 3 * np.pi * 1000, rel=0.03)

    holed = np.delete(triangles, [0, 7, 40], axis=0)  # three holes: each removed triangle leaves 3 boundary edges
    open_ = json.loads(voxelscope("info", _write(points, holed, tmp_path / f"holes{suffix}"), "--json").stdout)
    assert not open_["closed"] and open_["boundary_edges"] == 9 and open_["triangles"] == len(holed)
    assert open_["volume_mm3"] is None
    text = voxelscope("info", tmp_path / f"holes{suffix}").stdout
    assert "Closed       no (9 boundary edges" in text


@pytest.mark.parametrize("name, triangles, closed", [("stanford-bunny.obj.gz", 69451, False), ("spot.obj.gz", 5856, True),
                                                     ("fandisk.obj.gz", 12946, True), ("cow.obj.gz", 5804, True)])
def test_info_on_the_real_meshes(name, triangles, closed):
    path = SHARED_MESHES / name
    if not path.exists():
        pytest.skip(f"the shared test meshes are not at {SHARED_MESHES}")
    facts = json.loads(voxelscope("info", path, "--json").stdout)
    assert facts["triangles"] == triangles and facts["closed"] is closed
    if name.startswith("stanford-bunny"):
        assert facts["boundary_edges"] == 223  # the five holes in its base, as scanned
    else:
        assert facts["orientation"] == "outward" and facts["volume_mm3"] > 0


def test_damaged_mesh_is_one_line(tmp_path):
    path = tmp_path / "broken.stl"
    path.write_bytes(b"\0" * 80 + (1000).to_bytes(4, "little") + b"\1" * 50)
    process = voxelscope("info", path, check=False)
    assert process.returncode == 1
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and "broken.stl" in lines[0] and "Traceback" not in process.stderr
