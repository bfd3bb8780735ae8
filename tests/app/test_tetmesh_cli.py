"""``voxelscope tetmesh``: the files VTK and meshio read back, the JSON report, the sidecar, and one-line refusals of
bad inputs before any large allocation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from .test_cli import voxelscope


def _read_vtu(path):
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def test_sample_skull_at_h_1_5_mm_as_vtu_read_back_by_vtk_and_meshio(tmp_path):
    import meshio

    output = tmp_path / "skull.vtu"
    report = json.loads(voxelscope("tetmesh", "sample", "--iso", 300, "--h", 1.5, "-o", output, "--json").stdout)
    for key in ("tetrahedra", "points", "min_dihedral_deg", "max_dihedral_deg", "seconds", "quality"):
        assert key in report
    assert {"field", "cut", "warp", "stencil", "total"} <= set(report["seconds"])
    assert 10.7 <= report["min_dihedral_deg"] and report["max_dihedral_deg"] <= 164.8
    assert report["quality"]["conforming"] and report["quality"]["outside_bounds"] == 0
    grid = _read_vtu(output)
    assert (grid.GetNumberOfCells(), grid.GetNumberOfPoints()) == (report["tetrahedra"], report["points"])
    mesh = meshio.read(output)
    assert len(mesh.points) == report["points"] and len(mesh.cells_dict["tetra"]) == report["tetrahedra"]
    angles = mesh.cell_data_dict["min_dihedral_deg"]["tetra"]
    assert angles.min() == pytest.approx(report["min_dihedral_deg"], abs=1e-3)
    sidecar = json.loads((tmp_path / "skull.vtu.json").read_text())
    assert sidecar["h_mm"] == 1.5 and sidecar["iso"] == 300.0 and sidecar["alpha_long"] == 0.24999
    assert sidecar["quality"]["min_dihedral_deg"] == pytest.approx(report["min_dihedral_deg"])
    assert sidecar["coordinate_system"] == "LPS" and sidecar["counts"]["tetrahedra"] == report["tetrahedra"]


@pytest.mark.parametrize("suffix", [".msh", ".mesh", ".inp"])
def test_gmsh_medit_and_abaqus_files_load_in_meshio(tmp_path, suffix):
    import meshio

    output = tmp_path / f"skull{suffix}"
    report = json.loads(voxelscope("tetmesh", "sample", "--iso", 300, "--h", 4, "--alpha", "8.9", "-o", output,
                                   "--json").stdout)
    assert 8.9 <= report["min_dihedral_deg"] and report["max_dihedral_deg"] <= 158.8
    mesh = meshio.read(output)
    assert len(mesh.points) == report["points"]
    assert sum(len(c.data) for c in mesh.cells if c.type == "tetra") == report["tetrahedra"]


def test_existing_outputs_are_kept_unless_forced(tmp_path):
    output = tmp_path / "skull.vtu"
    output.write_text("keep me")
    process = voxelscope("tetmesh", "sample", "--h", 4, "-o", output, check=False)
    assert process.returncode == 1 and "--force" in process.stderr and output.read_text() == "keep me"
    voxelscope("tetmesh", "sample", "--h", 4, "-o", output, "--force")
    assert _read_vtu(output).GetNumberOfCells() > 0


@pytest.mark.parametrize("arguments, message", [
    (["--iso", 5000], "outside the values"),
    (["--h", 0.01], "GiB"),
    (["--h", 400], "larger than the volume"),
    (["--h", -1], "positive number of mm"),
])
def test_bad_inputs_give_one_line(tmp_path, arguments, message):
    process = voxelscope("tetmesh", "sample", *arguments, "-o", tmp_path / "x.vtu", check=False)
    assert process.returncode == 1
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in process.stderr
    assert not (tmp_path / "x.vtu").exists()


def test_an_empty_field_gives_one_line(tmp_path):
    from app.io import save_volume
    from app.volume import Volume

    path = save_volume(Volume(np.zeros((6, 6, 6), dtype=np.uint8)), tmp_path / "empty.nii.gz")
    process = voxelscope("tetmesh", path, "--iso", 0.5, "-o", tmp_path / "x.vtu", check=False)
    assert process.returncode == 1 and len(process.stderr.strip().splitlines()) == 1
    assert "empty" in process.stderr


def test_vtk_methods_write_too(tmp_path):
    output = tmp_path / "clip.vtu"
    report = json.loads(voxelscope("tetmesh", "sample", "--method", "vtk-delaunay", "-o", output,
                                   "--json").stdout)
    assert report["tetrahedra"] == _read_vtu(output).GetNumberOfCells() > 0
    assert report["stats"]["hull_tetrahedra"] >= report["tetrahedra"]


def test_render_draws_a_clipped_stuffing_view_and_refuses_a_malformed_plane(tmp_path):
    from app.pipeline.offscreen import read_png

    output = tmp_path / "stuffing.png"
    report = json.loads(voxelscope("render", "sample", "--mode", "stuffing", "--h", 4, "--clip-origin", "0 10 0",
                                   "--clip-normal", "0 -1 0", "--size", 200, 160, "-o", output, "--json").stdout)
    image = read_png(output)
    assert image.shape[:2] == (160, 200) and image.std() > 0
    # The JSON report carries the mesh's numbers, inside the angle bounds of the default alpha pair.
    stats = report["tetmesh"]
    assert stats["tetrahedra"] > 0 and 10.7 <= stats["min_dihedral_deg"] <= stats["max_dihedral_deg"] <= 164.8
    process = voxelscope("render", "sample", "--mode", "stuffing", "--clip-normal", "0 1", "-o",
                         tmp_path / "x.png", check=False)
    assert process.returncode == 1 and "three numbers" in process.stderr
    assert len(process.stderr.strip().splitlines()) == 1


def test_the_operation_makes_a_tetmesh_item_that_the_tetmesh_mode_shows():
    from app.datasets import ct_head_phantom
    from app.operations import get_operation
    from app.modes import get_mode
    from app.pipeline import RenderSettings, render_item
    from app.scene import VolumeItem

    volume = ct_head_phantom(shape=(54, 128, 128), spacing=(1.875, 1.875, 4.0))
    source = VolumeItem("ct", volume=volume)
    operation = get_operation("tetrahedra")
    result = operation.run({"volume": source}, operation.resolve_options({"h": 4.0}))
    item = result.item
    assert item.kind == "tetmesh" and item.grid.GetNumberOfCells() == result.report["tetrahedra"] > 0
    assert 10.7 <= result.report["min_dihedral_deg"] and result.report["max_dihedral_deg"] <= 164.8
    bounds = np.asarray(item.bounds).reshape(3, 2)
    world = np.asarray(source.bounds).reshape(3, 2)
    # in the patient, closed at most one voxel beyond the volume where the bone meets its last slice
    reach = np.asarray(volume.spacing)
    assert np.all(bounds[:, 0] >= world[:, 0] - reach) and np.all(bounds[:, 1] <= world[:, 1] + reach)
    assert bounds[2, 0] < world[2, 0]  # the vertebra column is cut by the first slice and closed below it
    picture = render_item(item, RenderSettings(mode=get_mode("tetmesh"), size=(96, 96)))
    assert picture.image.std() > 0


def test_the_vtk_filter_of_stuffing():
    from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    from algorithms.meshing.isosurface_stuffing.filter import IsosurfaceStuffingFilter

    axis = np.arange(32, dtype=np.float32) - 15.5
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    image = image_from_array(10.0 - np.sqrt(x * x + y * y + z * z), (1.0, 1.0, 1.0), (5.0, 0.0, 0.0))
    stuffing = IsosurfaceStuffingFilter()
    stuffing.SetInputDataObject(image)
    stuffing.SetLatticeSpacing(1.5)
    stuffing.SetAlpha("8.9")
    grid = run_algorithm(stuffing)
    angles = np.asarray([grid.GetCellData().GetArray("min_dihedral_deg").GetValue(i)
                         for i in range(grid.GetNumberOfCells())])
    assert grid.GetNumberOfCells() > 0 and angles.min() >= 8.9
    centre = np.mean([grid.GetPoint(i) for i in range(grid.GetNumberOfPoints())], axis=0)
    np.testing.assert_allclose(centre, (5.0 + 15.5, 15.5, 15.5), atol=0.3)  # the image's origin applied
