"""Cut-away tools in every render mode (issue 15, source 002 section 2.5): a render with ``--cut sphere:...``
agrees with the same mode's render of the volume whose voxels inside the sphere were set to the background value
beforehand, and differs clearly from the uncut render; the JSON reports of ``render``, ``mesh`` and ``convert``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from algorithms.compare.image_metrics import psnr_foreground
from app.modes import get_mode
from app.pipeline.headless import RenderSettings, render_item
from app.scene import VolumeItem
from app.cutaways import masked_volume, parse_cut

SPHERE = "sphere:0,-40,120,100"  # LPS mm: the top of the phantom's head (the vertex), seen from the anterior view
MESH_SPHERE = "sphere:30,-80,0,70"  # LPS mm: the front left of the skull (the frontal bone and the left orbit)
MODES = ("raymarch", "shear-warp", "slicing", "vtk-gpu", "vtk-cpu", "marching-cubes", "flying-edges", "voxel-faces")


@pytest.fixture(scope="module")
def items():
    from app.io import load_volume
    from app.samples import resolve_path

    volume = load_volume(resolve_path("sample"))
    sphere = parse_cut(SPHERE)
    return VolumeItem("sample", volume=volume), VolumeItem("pre-masked", volume=masked_volume(volume, [sphere])), sphere


@pytest.mark.parametrize("mode", MODES)
def test_cut_render_agrees_with_the_premasked_volume(items, mode):
    item, premasked, sphere = items
    settings = dict(mode=get_mode(mode), size=(128, 128), shading=False, parallel=mode == "shear-warp")
    cut = render_item(item, RenderSettings(tools=(sphere,), cut_evaluation="binary", **settings))
    reference = render_item(premasked, RenderSettings(**settings)).image
    plain = render_item(item, RenderSettings(**settings)).image
    agreement = psnr_foreground(cut.image, reference)
    versus_uncut = psnr_foreground(cut.image, plain)
    assert agreement >= 30.0, f"{mode}: {agreement:.1f} dB against the pre-masked volume's render"
    # Clearly different from the uncut render: far below the agreement and many foreground pixels changed.
    foreground = (cut.image.max(axis=-1) > 2) | (plain.max(axis=-1) > 2)
    changed = np.abs(cut.image.astype(np.int16) - plain.astype(np.int16)).max(axis=-1) > 25
    assert versus_uncut < 30.0 and versus_uncut <= agreement - 5.0, (mode, versus_uncut, agreement)
    assert changed[foreground].mean() > 0.05, mode
    assert cut.info["cut"]["tools"][0]["shape"] == "sphere"
    assert "seconds" in cut.info["cut"]


def test_modes_that_cannot_cut_say_so():
    from app.modes import modes

    refused = [m for m in modes() if not m.capabilities.accepts_cutaways and m.output in ("volume", "surface")]
    if not refused:
        pytest.skip("every volume and surface mode honours tools")
    item = VolumeItem("tiny", volume=_tiny_volume())
    with pytest.raises(ValueError, match="does not honour cut-away tools"):
        render_item(item, RenderSettings(mode=refused[0], size=(32, 32), tools=(parse_cut("sphere:0,0,0,5"),),
                                         parallel=True))


def _tiny_volume():
    from app.volume import Volume

    return Volume(np.zeros((8, 8, 8), dtype=np.int16), spacing=(1.0, 1.0, 1.0))


@pytest.mark.parametrize("spec, problem", [
    ("sphere:1,2,3", "expected sphere:X,Y,Z,R"),
    ("box:1,2,3,4,5,6,7", "expected box:X,Y,Z,SX,SY,SZ"),
    ("sphere:a,b,c,d", "must be numbers"),
    ("cube:1,2,3,4", "use one of"),
    ("sphere:0,0,0,-4", "positive radius"),
    ("mask:/nonexistent/mask.nii.gz", "does not exist"),
])
def test_bad_cut_specifications_get_one_line_errors(spec, problem):
    with pytest.raises(ValueError, match=problem):
        parse_cut(spec)


def voxelscope(*args, check=True):
    import subprocess
    import sys

    process = subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True,
                             timeout=900)
    if check and process.returncode != 0:
        raise AssertionError(f"voxelscope {' '.join(map(str, args))} failed:\n{process.stderr}")
    return process


def _cap_angles(path, centre, radius):
    """Angles (degrees) between the face normals of the triangles lying on the sphere (all three corners within
    0.05 mm of it) and the sphere's normal pointing into the removed ball (outward for what is left), with areas."""
    from algorithms.compare.triangles import surface_arrays
    from app.io.meshes import load_mesh

    points, triangles = surface_arrays(load_mesh(path).polydata)
    g = np.linalg.norm(points - centre, axis=1) - radius
    on_sphere = np.all(np.abs(g[triangles]) < 0.05, axis=1)
    corners = points[triangles[on_sphere]]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    areas = np.linalg.norm(normals, axis=1) / 2
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    inward = centre - corners.mean(axis=1)
    inward /= np.linalg.norm(inward, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normals, inward), -1.0, 1.0))), areas


def test_mesh_with_a_distance_cut_is_watertight_with_a_smooth_cap(tmp_path):
    centre, radius = np.array([30.0, -80.0, 0.0]), 70.0
    reports, caps = {}, {}
    for evaluation in ("distance", "binary"):
        out = tmp_path / f"cut-{evaluation}.stl"
        reports[evaluation] = json.loads(voxelscope("mesh", "sample", "--cut", MESH_SPHERE, "--cut-eval", evaluation,
                                                    "--close-edges", "-o", out, "--json").stdout)
        caps[evaluation] = _cap_angles(out, centre, radius)
    report = reports["distance"]
    assert report["validity"]["watertight"] and report["validity"]["manifold"]
    assert report["validity"]["outward_normals"]
    assert report["cut"]["evaluation"] == "distance" and report["cut"]["seconds"] > 0
    assert report["cut"]["tools"] == [{"shape": "sphere", "mode": "remove", "centre_mm": [30.0, -80.0, 0.0],
                                       "rotation_degrees": [0.0, 0.0, 0.0], "radius_mm": 70.0}]
    angles, areas = caps["distance"]
    # The cut face is a piece of the sphere (the skull's section, some 2000 mm^2), its normals the sphere's.
    assert areas.sum() > 1000.0
    assert areas[angles <= 5.0].sum() >= 0.99 * areas.sum(), np.percentile(angles, [50, 90, 99])
    assert np.median(angles) < 1.0
    # Binary evaluation: a stair-stepped cut whose corners do not lie on the sphere.
    assert caps["binary"][1].sum() < 0.05 * areas.sum()
    assert reports["binary"]["validity"]["watertight"]


def test_render_json_reports_the_tools_and_the_time_the_cut_added(tmp_path):
    out = tmp_path / "cut.png"
    report = json.loads(voxelscope("render", "sample", "--mode", "raymarch", "--size", 96, 96, "--cut", SPHERE,
                                   "--cut", "box:0,0,40,60,60,40,0,0,45", "-o", out, "--json").stdout)
    cut = report["cut"]
    assert [tool["shape"] for tool in cut["tools"]] == ["sphere", "box"]
    assert cut["tools"][1]["rotation_degrees"] == [0.0, 0.0, 45.0]
    assert cut["how"] == "per sample, no data rewrite"
    assert cut["frame_seconds"] > 0 and cut["uncut_frame_seconds"] > 0
    bad = voxelscope("render", "sample", "--mode", "raymarch", "--cut", "sphere:1,2", "-o", tmp_path / "bad.png",
                     check=False)
    assert bad.returncode != 0 and "Traceback" not in bad.stderr
    assert "expected sphere:X,Y,Z,R" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_convert_with_a_keep_box_writes_the_cropped_region_on_the_volume_grid(tmp_path):
    from app.io import load_volume
    from app.samples import resolve_path

    out = tmp_path / "roi.nii.gz"
    report = json.loads(voxelscope("convert", "sample", "--cut", "box:10,-20,5,40,30,20", "--cut-mode", "keep",
                                   "-o", out, "--json").stdout)
    assert report["cut"]["tools"][0]["mode"] == "keep"
    original = load_volume(resolve_path("sample"))
    cropped = load_volume(out)
    assert np.allclose(cropped.spacing, original.spacing)
    # The box spans 40 x 30 x 20 mm: the voxel centres inside it, on the original grid.
    expected = [int(np.floor(size / s)) + d for size, s, d in zip((40, 30, 20), original.spacing, (0, 0, 0))]
    assert all(abs(n - e) <= 1 for n, e in zip(cropped.dimensions, expected)), (cropped.dimensions, expected)
    low = np.asarray(cropped.origin)
    assert np.all(low >= np.array([10 - 20, -20 - 15, 5 - 10]) - 1e-6)
    assert np.all(low <= np.array([10 - 20, -20 - 15, 5 - 10]) + np.asarray(original.spacing))
    # The values are the original's at the same world positions.
    offset = np.rint((low - np.asarray(original.origin)) / np.asarray(original.spacing)).astype(int)
    nx, ny, nz = cropped.dimensions
    block = original.array[offset[2]:offset[2] + nz, offset[1]:offset[1] + ny, offset[0]:offset[0] + nx]
    assert np.array_equal(cropped.array, block)
