"""``voxelscope distance`` and ``voxelscope csg``: the JSON reports, the files written, and one-line errors for
damaged meshes and mismatched inputs."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

MESHES = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "meshes"


def voxelscope(*args):
    return subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def _one_line_error(process, *words):
    assert process.returncode != 0
    lines = [line for line in process.stderr.strip().splitlines() if not line.startswith("voxelscope: warning")]
    assert len(lines) == 1, process.stderr
    assert "Traceback" not in process.stderr
    for word in words:
        assert word in lines[0], lines[0]


@pytest.fixture(scope="module")
def meshes():
    if not MESHES.exists():
        pytest.skip(f"the shared test meshes are not here ({MESHES})")
    return MESHES


def _box_obj(path, low, high, *, drop_last=False):
    (x0, y0, z0), (x1, y1, z1) = low, high
    corners = [(x, y, z) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    if drop_last:
        faces = faces[:-1]
    text = "".join(f"v {x} {y} {z}\n" for x, y, z in corners) + "".join(
        f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
    path.write_text(text)
    return path


def test_distance_json_and_field(tmp_path, meshes):
    from app.io import load_volume

    out = tmp_path / "spot.nii.gz"
    process = voxelscope("distance", meshes / "spot.obj.gz", "--grid", 40, "--band", "5%", "--outside", "propagate",
                         "-o", out, "--json")
    assert process.returncode == 0, process.stderr
    report = json.loads(process.stdout)
    assert set(report["seconds"]) >= {"sign", "band", "outside", "total"}
    low, high = report["value_range_mm"]
    assert low < 0 < high and high > report["band_mm"]  # propagated beyond the band
    volume = load_volume(out)
    assert volume.array.shape == tuple(report["dimensions"][::-1])
    assert np.isclose(volume.array.min(), low) and report["inside_voxels"] == int((volume.array < 0).sum())
    again = voxelscope("distance", meshes / "spot.obj.gz", "--grid", 40, "-o", out)
    _one_line_error(again, "already exists", "--force")


def test_csg_writes_a_watertight_mesh_and_reports_times(tmp_path, meshes):
    a = _box_obj(tmp_path / "a.obj", (0, 0, 0), (20, 20, 20))
    b = _box_obj(tmp_path / "b.obj", (10, 10, 10), (30, 30, 30))
    out = tmp_path / "a_minus_b.stl"
    process = voxelscope("csg", a, "--subtract", b, "--spacing", 0.5, 0.5, 0.5, "--band", "2", "-o", out, "--json")
    assert process.returncode == 0, process.stderr
    report = json.loads(process.stdout)
    assert set(report["seconds"]) >= {"boolean", "meshing"}
    validity = report["validity"]
    assert validity["watertight"] and validity["manifold"] and validity["outward_normals"]
    assert validity["volume_mm3"] == pytest.approx(20 ** 3 - 10 ** 3, rel=0.01)
    assert out.exists()
    field_out = tmp_path / "union.nrrd"
    union = voxelscope("csg", a, "--union", b, "--spacing", 0.5, 0.5, 0.5, "-o", field_out, "--json")
    assert union.returncode == 0, union.stderr
    # the written field combines again with a mesh (resampled onto the mesh's grid when the grids differ)
    again = voxelscope("csg", field_out, "--intersect", a, "--grid", 40, "-o", tmp_path / "x.ply", "--json")
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout)["validity"]["volume_mm3"] == pytest.approx(20 ** 3, rel=0.03)


def test_damaged_and_mismatched_inputs_give_one_line(tmp_path, meshes):
    holed = _box_obj(tmp_path / "holed.obj", (0, 0, 0), (10, 10, 10), drop_last=True)
    box = _box_obj(tmp_path / "box.obj", (0, 0, 0), (10, 10, 10))
    far = _box_obj(tmp_path / "far.obj", (500, 500, 500), (510, 510, 510))
    _one_line_error(voxelscope("distance", holed, "--grid", 32, "-o", tmp_path / "h.nii.gz"), "holed", "open",
                    "--inside winding")
    _one_line_error(voxelscope("distance", tmp_path / "missing.stl", "--grid", 32, "-o", tmp_path / "m.nii.gz"),
                    "missing.stl")
    _one_line_error(voxelscope("distance", box, "--grid", 32, "-o", tmp_path / "m.txt"), "m.txt", ".nii.gz")
    _one_line_error(voxelscope("distance", box, "--grid", 32, "--band", "-3", "-o", tmp_path / "b.nii.gz"), "band")
    _one_line_error(voxelscope("distance", far, "--like", "sample", "-o", tmp_path / "s.nii.gz"), "far", "outside")
    _one_line_error(voxelscope("distance", box, "--grid", 1200, "-o", tmp_path / "g.nii.gz"), "GiB")
    _one_line_error(voxelscope("csg", box, "--union", holed, "--grid", 32, "-o", tmp_path / "u.stl"), "holed")
    _one_line_error(voxelscope("csg", box, "--subtract", box, "--grid", 32, "-o", tmp_path / "e.stl"), "empty")
    _one_line_error(voxelscope("csg", box, "--union", box, box, box, box, "--grid", 16, "-o", tmp_path / "f.stl"),
                    "two to four")
    _one_line_error(voxelscope("csg", box, "--intersect", far, "--grid", 32, "-o", tmp_path / "i.stl"),
                    "empty")
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"solid x\nfacet normal 0 0 1\n outer loop\n vertex 0 0\n")
    _one_line_error(voxelscope("csg", broken, "--union", box, "--grid", 32, "-o", tmp_path / "k.stl"), "broken.stl")
    _one_line_error(voxelscope("csg", box, "--union", "sample", "--blend", "-1", "-o", tmp_path / "l.stl"), "blend")
