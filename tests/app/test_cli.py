"""The command line end to end: real processes, real files, JSON as documented, errors without tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.io import load_volume, save_volume
from app.pipeline import read_png

from .dicom_helpers import small_ct, write_scanner_folder

INFO_KEYS = {"dimensions", "spacing", "origin", "direction", "dtype", "range", "modality", "units", "world_bounds",
             "source_format", "warnings"}


def voxelscope(*args, check=True):
    """Run the installed command line in a fresh process (like a user would)."""
    process = subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True,
                             timeout=600)
    if check and process.returncode != 0:
        raise AssertionError(f"voxelscope {' '.join(map(str, args))} failed:\n{process.stderr}")
    return process


def info_json(path) -> dict:
    output = voxelscope("info", path, "--json").stdout
    data = json.loads(output)  # exactly one JSON object
    assert INFO_KEYS <= set(data)
    return data


def test_info_on_scanner_folder_and_its_nifti(tmp_path):
    volume = small_ct()
    write_scanner_folder(volume, tmp_path / "dicom")
    facts = info_json(tmp_path / "dicom")
    assert facts["dimensions"] == list(volume.dimensions)
    assert facts["spacing"] == pytest.approx(list(volume.spacing))
    assert facts["range"] == [float(volume.array.min()), float(volume.array.max())]
    assert facts["units"] == "HU" and facts["modality"] == "CT"
    assert facts["origin"] == pytest.approx(list(volume.origin))
    assert facts["direction"] == pytest.approx(list(np.eye(3).ravel()))
    assert facts["world_bounds"] == pytest.approx(list(volume.world_bounds))
    assert facts["source_format"] == "DICOM series"
    assert facts["other_series"][0]["description"] == "Topogram"

    voxelscope("convert", tmp_path / "dicom", "-o", tmp_path / "same.nii.gz")
    nifti = info_json(tmp_path / "same.nii.gz")
    for key in ("dimensions", "spacing", "direction", "origin", "range", "units"):
        assert nifti[key] == pytest.approx(facts[key]) if key != "units" else nifti[key] == facts[key]

    text = voxelscope("info", tmp_path / "dicom").stdout
    assert "Not used     series" in text and "Topogram" in text and "HU" in text and "LPS" in text


def test_truncated_and_stray_files_warn_by_name(tmp_path):
    from app.io import write_dicom_series

    folder = tmp_path / "dicom"
    paths = write_dicom_series(small_ct(), folder, rescale_intercept=-1024)
    paths[-1].write_bytes(paths[-1].read_bytes()[:-300])
    (folder / "readme.txt").write_text("exported by the PACS")
    process = voxelscope("info", folder)
    assert f"Warning      {paths[-1]}: skipped" in process.stdout
    assert "readme.txt: skipped, not a DICOM file" in process.stdout
    assert "Traceback" not in process.stdout + process.stderr


def test_errors_are_one_clear_line(tmp_path):
    (tmp_path / "bad.nii").write_bytes(b"not a nifti file at all" * 20)
    for args in (("info", tmp_path / "missing.nii"), ("info", tmp_path / "bad.nii"),
                 ("render", "sample", "--mode", "vtk-cpu", "-o", tmp_path / "x.jpg")):
        process = voxelscope(*args, check=False)
        assert process.returncode != 0
        lines = process.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("voxelscope: error: "), process.stderr
        assert "Traceback" not in process.stderr
    assert "missing.nii: no such file or folder" in voxelscope("info", tmp_path / "missing.nii", check=False).stderr
    debug = voxelscope("--debug", "info", tmp_path / "missing.nii", check=False)
    assert "Traceback" in debug.stderr


@pytest.mark.parametrize("mode", ["vtk-gpu", "vtk-cpu"])
def test_render_volume_modes_on_the_sample(tmp_path, mode):
    out = tmp_path / f"{mode}.png"
    process = voxelscope("render", "sample", "--mode", mode, "-o", out, "--size", 160, 128, "--frames", 3,
                         "--azimuth", 30, "--json")
    report = json.loads(process.stdout)
    for key in ("frame_seconds", "mean_frame_seconds", "weighted_mean_frame_seconds", "setup_seconds"):
        assert report[key] > 0
    assert report["frames"] == 3 and report["mode"] == mode
    image = read_png(out)
    assert image.shape == (128, 160, 3)
    # The skull is in the middle of a black background.
    assert image[0, 0].max() == 0 and image[64, 80].max() > 40
    assert voxelscope("render", "sample", "--mode", mode, "-o", out, check=False).returncode == 1  # no overwrite


def test_mesh_close_edges_caps_the_skull_at_the_last_slice(tmp_path):
    # 160 mm of slices through the phantom's head: the skull runs into the first and the last slice, so the plain
    # surface is open there and the capped one closed.
    from app.datasets import ct_head_phantom

    head = save_volume(ct_head_phantom((40, 96, 96), (2.4, 2.4, 4.0)), tmp_path / "head.nii.gz")
    reports = {}
    for extra in ((), ("--close-edges",)):
        out = tmp_path / f"skull{len(extra)}.stl"
        reports[extra] = json.loads(voxelscope("mesh", head, "--method", "marching-cubes", "--iso", 300, "-o", out,
                                               "--json", *extra).stdout)
    plain, capped = reports[()], reports[("--close-edges",)]
    assert not plain["validity"]["watertight"]
    assert capped["validity"]["watertight"] and capped["validity"]["manifold"]
    assert capped["validity"]["outward_normals"]
    assert capped["triangles"] > plain["triangles"]
    # The cap adds area only where the skull meets the volume's edge (its first and last slice, and the front of
    # the grid, which cuts the face): away from the edges the two surfaces are the same, and what is added covers at
    # least the skull's sections in the volume's faces.
    volume = load_volume(head)
    spacing = np.asarray(volume.spacing)
    low = np.asarray(volume.origin) + 2 * spacing
    high = np.asarray(volume.origin) + (np.asarray(volume.dimensions) - 3) * spacing
    inner = {}
    for name in ("skull0.stl", "skull1.stl"):
        centres, areas = _triangle_centres_and_areas(tmp_path / name)
        inner[name] = areas[np.all((centres > low) & (centres < high), axis=1)].sum()
    assert inner["skull1.stl"] == pytest.approx(inner["skull0.stl"], rel=1e-6)
    bone = volume.array >= 300
    sx, sy, sz = spacing
    sections = (np.count_nonzero(bone[[0, -1]]) * sx * sy + np.count_nonzero(bone[:, [0, -1]]) * sx * sz
                + np.count_nonzero(bone[:, :, [0, -1]]) * sy * sz)
    assert sections > 0
    assert capped["validity"]["area_mm2"] - plain["validity"]["area_mm2"] > 0.9 * sections
    sidecar = json.loads((tmp_path / "skull1.stl.json").read_text())
    assert sidecar["parameters"]["close_edges"] is True


def _triangle_centres_and_areas(path):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOGeometry import vtkSTLReader

    reader = vtkSTLReader()
    reader.SetFileName(str(path))
    reader.Update()
    mesh = reader.GetOutput()
    points = vtk_to_numpy(mesh.GetPoints().GetData()).astype(np.float64)
    corners = points[vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()).reshape(-1, 3)]
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    return corners.mean(axis=1), areas


def test_render_slicing_through_opengl_matches_the_float_path(tmp_path):
    from algorithms.compare.image_metrics import psnr_foreground

    images = {}
    for compositing in ("gl", "float"):
        out = tmp_path / f"slicing-{compositing}.png"
        report = json.loads(voxelscope("render", "sample", "--mode", "slicing", "--compositing", compositing,
                                       "--slices", 96, "-o", out, "--size", 160, 128, "--frames", 2, "--json").stdout)
        assert report["options"] == {"slices": 96, "compositing": compositing} and report["frames"] == 2
        images[compositing] = read_png(out)
    assert images["gl"][64, 80].max() > 40 and images["gl"][0, 0].max() == 0
    # Same slices, blended in an 8-bit framebuffer by OpenGL or in float by us.
    assert psnr_foreground(images["gl"] / 255.0, images["float"] / 255.0) > 40.0  # measured 52 dB


def test_render_surface_mode_and_background(tmp_path):
    out = tmp_path / "fe.png"
    report = json.loads(voxelscope("render", "sample:mri", "--mode", "flying-edges", "-o", out, "--size", 96, 96,
                                   "--background", 255, 255, 255, "--json").stdout)
    assert report["surface"]["triangles"] > 1000
    image = read_png(out)
    assert tuple(image[0, 0]) == (255, 255, 255)


def test_mesh_flying_edges_json_and_files(tmp_path):
    out = tmp_path / "skull.stl"
    report = json.loads(voxelscope("mesh", "sample", "--method", "flying-edges", "--iso", 300, "-o", out,
                                   "--json").stdout)
    for key in ("points", "triangles", "cells", "strips", "bytes", "seconds"):
        assert key in report
    assert report["triangles"] > 10000 and report["strips"] == 0
    assert report["bytes"] == report["points"] * 12 + report["triangles"] * 12
    assert out.exists() and Path(str(out) + ".json").exists()
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert sidecar["iso_value"] == 300 and sidecar["method"] == "flying-edges"
    assert sidecar["coordinate_system"] == "LPS" and sidecar["length_units"] == "mm"

    from vtkmodules.vtkIOGeometry import vtkSTLReader

    reader = vtkSTLReader()
    reader.SetFileName(str(out))
    reader.MergingOff()
    reader.Update()
    # The file holds the extracted triangles minus those of zero area (the isovalue equals sample values here).
    assert reader.GetOutput().GetNumberOfCells() == report["written"]["triangles"] == sidecar["counts"]["triangles"]
    assert 0.99 * report["triangles"] < report["written"]["triangles"] <= report["triangles"]
    # LPS mm: the 300 HU surface is the skull's outer table, the ellipsoid of semi-axes 96, 120 and 125 mm centred on
    # the origin (the phantom's definition), within a voxel (0.55 x 0.55 x 1.5 mm).
    bounds = reader.GetOutput().GetBounds()
    np.testing.assert_allclose(bounds, (-96.0, 96.0, -120.0, 120.0, -125.0, 125.0), atol=1.5)

    refused = voxelscope("mesh", "sample", "--method", "flying-edges", "-o", out, check=False)
    assert refused.returncode == 1 and "already exists" in refused.stderr


def test_convert_and_series_listing(tmp_path):
    volume = small_ct()
    write_scanner_folder(volume, tmp_path / "dicom")
    listing = json.loads(voxelscope("series", tmp_path / "dicom", "--json").stdout)["series"]
    assert [s["slices"] for s in listing] == [volume.dimensions[2], 1]
    save_volume(volume, tmp_path / "v.mha")
    voxelscope("convert", tmp_path / "v.mha", "-o", tmp_path / "v.vti")
    assert info_json(tmp_path / "v.vti")["dimensions"] == list(volume.dimensions)


def test_raw_on_the_command_line(tmp_path):
    values = np.arange(4 * 5 * 6, dtype=np.uint16).reshape(6, 5, 4)
    (tmp_path / "v.raw").write_bytes(values.tobytes())
    facts = info_json_args(tmp_path / "v.raw", "--raw-dims", 4, 5, 6, "--raw-dtype", "uint16", "--raw-spacing", 1, 1, 2)
    assert facts["dimensions"] == [4, 5, 6] and facts["spacing"] == [1, 1, 2] and facts["range"] == [0, 119]


def info_json_args(*args) -> dict:
    return json.loads(voxelscope("info", *args, "--json").stdout)


@pytest.fixture(scope="module")
def colin_crop(tmp_path_factory):
    """A 70 x 80 x 60 voxel block of the real Colin 27 MRI (geometry kept), written as NIfTI."""
    from app.io import load_volume
    from app.samples import sample_path

    crop = load_volume(sample_path("mri")).crop((55, 125), (60, 140), (60, 120))
    return save_volume(crop, tmp_path_factory.mktemp("colin") / "colin_crop.nii.gz")


def test_voxel_methods_agree_with_vtk_threshold_surface(tmp_path, colin_crop):
    from algorithms.common.vtk_bridge import image_from_array
    from algorithms.references.vtk_surfaces import vtk_threshold_surface
    from app.io import load_volume

    reports = {}
    for method in ("voxel-faces", "tower", "hybrid"):
        reports[method] = json.loads(voxelscope("mesh", colin_crop, "--method", method, "--iso", 80, "-o",
                                                tmp_path / f"{method}.vtp", "--json").stdout)
    counts = {method: report["triangles"] for method, report in reports.items()}
    volume = load_volume(colin_crop)
    quads = vtk_threshold_surface(image_from_array(volume.array, volume.spacing, cell_data=True), 80.0)
    assert set(counts.values()) == {2 * quads.GetNumberOfCells()}, counts
    # Strips store no indices: fewer bytes than the indexed baseline.
    assert reports["tower"]["strips"] > 0 and reports["tower"]["bytes"] < reports["voxel-faces"]["bytes"]
    assert reports["voxel-faces"]["strips"] == 0


def test_marching_cubes_mesh_for_a_clinician(tmp_path):
    out = tmp_path / "skull.stl"
    report = json.loads(voxelscope("mesh", "sample", "--method", "marching-cubes", "--iso", 300, "--smooth", 20,
                                   "--decimate", 0.5, "--largest", "-o", out, "--json").stdout)
    validity = report["validity"]
    assert validity["manifold"] and validity["outward_normals"] and validity["components"] == 1
    assert report["written"]["triangles"] < 0.6 * report["triangles"]  # decimated by half
    sidecar = json.loads(Path(str(out) + ".json").read_text())
    assert sidecar["parameters"] == {"stride": 1, "close_edges": False, "smooth_iterations": 20, "smooth_passband": 0.1,
                                     "decimate": 0.5, "largest_component": True,
                                     "decimation": "quadric (vtkQuadricDecimation, volume preserving)",
                                     "decimation_achieved": 0.5}
    assert sidecar["validity"] == validity and sidecar["method"] == "marching-cubes"
    from vtkmodules.vtkIOGeometry import vtkSTLReader

    reader = vtkSTLReader()
    reader.SetFileName(str(out))
    reader.MergingOff()
    reader.Update()
    assert reader.GetOutput().GetNumberOfCells() == report["written"]["triangles"]
