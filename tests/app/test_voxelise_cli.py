"""``voxelscope voxelise``: the written mask reproduces every voxel centre, the JSON report, the bunny's holes
(refused by parity with a count, a solid by the winding rule), and one-line messages for damaged or unsuitable
meshes, never a traceback."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.algorithms.fields._voxelise_shapes import box, torus

from .test_cli import voxelscope

MESHES = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "meshes"
BUNNY = MESHES / "stanford-bunny.obj.gz"
REPORT_KEYS = {"dimensions", "spacing", "origin", "direction", "inside_voxels", "volume_mm3", "mesh_volume_mm3",
               "rule", "seconds", "mesh"}


def _obj(path: Path, points, triangles) -> Path:
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in np.asarray(points, dtype=float).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(triangles).tolist()]
    path.write_text("\n".join(lines) + "\n")
    return path


def _one_line_error(process, *needles):
    assert process.returncode == 1, process.stdout
    lines = process.stderr.strip().splitlines()
    assert "Traceback" not in process.stderr
    errors = [line for line in lines if line.startswith("voxelscope: error:")]
    assert len(errors) == 1 and len(lines) == 1, process.stderr
    for needle in needles:
        assert needle in errors[0], errors[0]


def test_grid_n_writes_a_mask_whose_geometry_reproduces_every_voxel_centre(tmp_path):
    from algorithms.fields.voxelise import voxelise
    from app.io import load_volume

    points, triangles = torus(40.0, 15.0, around=64, across=32, centre=(10.0, -20.0, 5.0))
    mesh = _obj(tmp_path / "ring.obj", points, triangles)
    output = tmp_path / "ring.nrrd"
    report = json.loads(voxelscope("voxelise", mesh, "--grid", 60, "-o", output, "--json").stdout)
    assert REPORT_KEYS <= set(report) and report["rule"] == "parity"
    # 60 voxels along the longest side (x and y: 110 mm) plus 2 voxels of padding on each side, cubic voxels
    assert report["dimensions"][0] == 64 and len(set(report["spacing"])) == 1
    assert report["mesh"]["triangles"] == len(triangles)
    written = load_volume(output)
    assert written.dimensions == tuple(report["dimensions"])
    assert np.allclose(written.spacing, report["spacing"]) and np.allclose(written.origin, report["origin"])
    # the reader's grid gives the same voxel centres, so voxelising there gives the file's mask voxel for voxel
    assert np.array_equal(written.array != 0, voxelise(points, triangles, written.grid) != 0)
    assert report["inside_voxels"] == int(np.count_nonzero(written.array))
    voxel = float(np.prod(report["spacing"]))
    assert report["volume_mm3"] == pytest.approx(report["inside_voxels"] * voxel)
    # a coarse torus of 64 x 32 quads: its own volume, and the voxel volume within 2 % of it
    assert report["volume_mm3"] == pytest.approx(report["mesh_volume_mm3"], rel=0.02)
    assert report["seconds"] > 0  # reported; how long it takes is the benchmark's business


def test_like_copies_the_volume_grid_and_spacing_gives_anisotropic_voxels(tmp_path):
    from app.io import load_volume
    from app.samples import sample_path

    ct = load_volume(sample_path("ct"))
    low = np.asarray(ct.grid.index_to_world(np.zeros((1, 3))))[0]
    high = np.asarray(ct.grid.index_to_world((np.asarray(ct.dimensions) - 1)[None, :].astype(float)))[0]
    centre = (low + high) / 2
    points, triangles = box(centre - 20.0, centre + 20.0)
    mesh = _obj(tmp_path / "cube.obj", points, triangles)
    like = json.loads(voxelscope("voxelise", mesh, "--like", "sample", "-o", tmp_path / "a.vti", "--json").stdout)
    assert like["dimensions"] == list(ct.dimensions)
    assert np.allclose(like["spacing"], ct.spacing) and np.allclose(like["origin"], ct.origin)
    assert np.allclose(like["direction"], np.ravel(ct.direction))
    aniso = json.loads(voxelscope("voxelise", mesh, "--spacing", 0.5, 0.5, 2, "--padding", 0, "-o",
                                  tmp_path / "b.nii.gz", "--json").stdout)
    assert aniso["spacing"] == pytest.approx([0.5, 0.5, 2.0])
    # a 40 mm cube with voxel centres on its faces, half-open by simulation of simplicity: 80 x 80 x 20 voxels
    assert aniso["inside_voxels"] == 80 * 80 * 20 and aniso["volume_mm3"] == pytest.approx(64_000)


def test_existing_output_is_kept_unless_forced(tmp_path):
    points, triangles = box((0, 0, 0), (10, 10, 10))
    mesh = _obj(tmp_path / "cube.obj", points, triangles)
    output = tmp_path / "cube.nii.gz"
    output.write_text("keep me")
    _one_line_error(voxelscope("voxelise", mesh, "--grid", 16, "-o", output, check=False), "--force")
    assert output.read_text() == "keep me"
    voxelscope("voxelise", mesh, "--grid", 16, "-o", output, "--force")
    assert output.stat().st_size > len("keep me")


@pytest.mark.skipif(not BUNNY.exists(), reason="the shared meshes (../shared/data/meshes) are not present")
def test_bunny_holes_are_reported_by_parity_and_closed_by_winding(tmp_path):
    refused = voxelscope("voxelise", BUNNY, "--grid", 64, "-o", tmp_path / "p.nii.gz", check=False)
    _one_line_error(refused, "223 boundary edges", "5 hole(s)", "--inside winding")
    assert not (tmp_path / "p.nii.gz").exists()
    process = voxelscope("voxelise", BUNNY, "--grid", 128, "--inside", "winding", "-o", tmp_path / "w.nii.gz",
                         "--json")
    report = json.loads(process.stdout)
    assert report["rule"] == "winding" and report["holes_closed"] == 5
    assert report["mesh"]["boundary_edges"] == 223
    assert "5 hole(s)" in process.stderr and "winding-number rule closes them" in process.stderr
    # the solid the user expects: the voxel volume within 1 % of the volume of the bunny closed over its holes
    assert report["mesh_volume_measured_on"].startswith("mesh closed by fans")
    assert report["volume_mm3"] == pytest.approx(report["mesh_volume_mm3"], rel=0.01)


def _cube():
    return box((0.0, 0.0, 0.0), (20.0, 20.0, 20.0))


def _damaged(kind: str, tmp_path: Path) -> tuple[Path, list]:
    """A damaged or unsuitable mesh file and the extra arguments it is voxelised with."""
    points, triangles = _cube()
    if kind == "empty":
        path = tmp_path / "empty.obj"
        path.write_text("")
        return path, []
    if kind == "no faces":
        path = tmp_path / "points.obj"
        path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
        return path, []
    if kind == "single triangle":
        return _obj(tmp_path / "one.obj", points, triangles[:1]), []
    if kind == "open":
        return _obj(tmp_path / "open.obj", points, triangles[2:]), []  # the bottom face is missing
    if kind == "non-manifold":  # a fin on an edge of the cube: that edge is shared by three triangles
        fin = np.vstack([points, [[10.0, -10.0, 0.0]]])
        return _obj(tmp_path / "fin.obj", fin, np.vstack([triangles, [[0, 1, 8]]])), []
    if kind == "flipped":
        return _obj(tmp_path / "flipped.obj", points, triangles[:, ::-1]), ["--inside", "winding"]
    if kind == "nan":
        path = _obj(tmp_path / "nan.obj", points, triangles)
        path.write_text(path.read_text().replace("v 0 0 0", "v nan 0 0", 1))
        return path, []
    if kind == "outside like":
        return _obj(tmp_path / "far.obj", points + 10_000.0, triangles), ["--like", "sample"]
    raise AssertionError(kind)


@pytest.mark.parametrize("kind, needles", [
    ("empty", ["empty.obj", "empty"]),
    ("no faces", ["points.obj", "no faces"]),
    ("single triangle", ["one.obj", "encloses no volume", "closed surface"]),
    ("open", ["open.obj", "is open: 4 boundary edges around 1 hole(s)", "--inside winding"]),
    ("non-manifold", ["fin.obj", "shared by 3 or more triangles", "--inside winding"]),
    ("flipped", ["flipped.obj", "faces inward", "--inside parity"]),
    ("nan", ["nan.obj", "NaN"]),
    ("outside like", ["far.obj", "lies outside", "LPS"]),
])
def test_damaged_or_unsuitable_meshes_give_one_line(tmp_path, kind, needles):
    path, extra = _damaged(kind, tmp_path)
    if extra[:1] != ["--like"]:
        extra = [*extra, "--grid", 32]
    output = tmp_path / "mask.nii.gz"
    _one_line_error(voxelscope("voxelise", path, *extra, "-o", output, check=False), *needles)
    assert not output.exists()


def test_flipped_mesh_is_voxelised_by_parity_with_a_warning(tmp_path):
    points, triangles = _cube()
    path = _obj(tmp_path / "flipped.obj", points, triangles[:, ::-1])
    process = voxelscope("voxelise", path, "--spacing", 1, 1, 1, "--padding", 1, "-o", tmp_path / "m.nii.gz",
                         "--json")
    report = json.loads(process.stdout)
    assert "faces inward" in process.stderr and report["warnings"]
    # voxel centres 1 mm apart on the cube's faces: a centre on a face counts as inside on the low side and as
    # outside on the high side (simulation of simplicity), so exactly 20 of the 21 centres per axis are inside
    assert report["inside_voxels"] == 20 ** 3


@pytest.mark.parametrize("arguments, needles", [
    (["--grid", 16, "--spacing", 1, 1, 1], ["not allowed with"]),
    ([], ["one of the arguments --grid --like --spacing is required"]),
])
def test_grid_choices_are_exclusive_and_required(tmp_path, arguments, needles):
    points, triangles = _cube()
    path = _obj(tmp_path / "cube.obj", points, triangles)
    process = voxelscope("voxelise", path, *arguments, "-o", tmp_path / "m.nii.gz", check=False)
    assert process.returncode == 2 and "Traceback" not in process.stderr
    assert all(needle in process.stderr for needle in needles)
