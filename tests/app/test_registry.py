"""The mode registry is the one extension point: a mode registered at run time, from this test module and nothing
else, appears in ``voxelscope modes``, gets its command-line flags, renders through the shared pipeline, and its
options are validated in one place."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from app.modes import Option, get_mode, mode_names, modes, register_mode, unregister_mode
from app.modes.surfaces import SurfaceMode

from .._registered_mode import TEST_MODE, shifted_faces


@pytest.fixture
def test_mode():
    register_mode(TEST_MODE)
    yield TEST_MODE
    unregister_mode(TEST_MODE.name)


def test_a_mode_registered_at_run_time_reaches_the_command_line(test_mode, capsys, tmp_path):
    assert main(["modes", "--json"]) == 0
    listed = {mode["name"]: mode for mode in json.loads(capsys.readouterr().out)["modes"]}
    assert listed["test-shifted-faces"]["options"] == [{
        "name": "shift", "flag": "--shift", "type": "float", "default": 0.0, "unit": "HU", "minimum": -5000,
        "maximum": 5000, "choices": None, "help": "test mode: added to the isovalue"}]
    assert listed["test-shifted-faces"]["output"] == "surface" and listed["raymarch"]["output"] == "image"

    # Its option is a flag of `render`, and it renders (a plain 2-voxel block: the faces are there at shift 0 and
    # gone when the shift lifts the threshold above the block's value: an empty surface is a one-line error and no
    # picture, issue 17).
    from app.io import save_volume
    from app.volume import Volume

    block = np.zeros((6, 6, 6), np.int16)
    block[2:4, 2:4, 2:4] = 100
    path = save_volume(Volume(block, units="HU", modality="CT"), tmp_path / "block.nii.gz")
    out = tmp_path / "shift0.png"
    assert main(["render", str(path), "--mode", "test-shifted-faces", "--iso", "50", "--shift", "0",
                 "-o", str(out), "--size", "64", "64", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["surface"]["triangles"] == 2 * 24 and report["options"] == {"shift": 0.0} and out.exists()
    out = tmp_path / "shift200.png"
    assert main(["render", str(path), "--mode", "test-shifted-faces", "--iso", "50", "--shift", "200",
                 "-o", str(out), "--size", "64", "64", "--json"]) == 1
    captured = capsys.readouterr()
    assert captured.out == "" and not out.exists()
    assert captured.err.strip().splitlines() == [
        "voxelscope: error: block.nii.gz: no surface to draw at 50 HU: there is none; the values run from 0 to 100 "
        "HU; nothing was written; choose another isovalue"]
    # The mode validates its flag; other modes refuse it by name.
    assert main(["render", str(path), "--mode", "test-shifted-faces", "--shift", "1e9", "-o",
                 str(tmp_path / "x.png")]) == 1
    assert "--shift must be at most 5000 HU" in capsys.readouterr().err
    assert main(["render", str(path), "--mode", "vtk-gpu", "--shift", "3", "-o", str(tmp_path / "y.png")]) == 1
    error = capsys.readouterr().err.strip()
    assert error == "voxelscope: error: --shift does not apply to mode 'vtk-gpu' (its options: none)"


def test_mesh_command_takes_surface_modes_and_their_options(test_mode, capsys, tmp_path):
    from app.io import save_volume
    from app.volume import Volume

    block = np.zeros((6, 6, 6), np.int16)
    block[2:4, 2:4, 2:4] = 100
    path = save_volume(Volume(block), tmp_path / "block.nii.gz")
    out = tmp_path / "block.stl"
    assert main(["mesh", str(path), "--method", "test-shifted-faces", "--iso", "50", "--shift", "-10", "-o",
                 str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["triangles"] == 48 and report["options"] == {"shift": -10.0}
    sidecar = json.loads(out.with_name("block.stl.json").read_text())
    assert sidecar["parameters"]["shift"] == -10.0 and sidecar["method"] == "test-shifted-faces"


def test_modes_list_every_family_and_group_them():
    names = mode_names()
    for expected in ("marching-cubes", "flying-edges", "voxel-faces", "tower", "hybrid", "raymarch", "slicing",
                     "slicing-axis", "shear-warp", "vtk-gpu", "vtk-cpu", "raymarch-vs-vtk-gpu", "mesh"):
        assert expected in names
    groups = [mode.group for mode in modes()]
    assert groups == sorted(groups, key=["Surfaces", "Volume rendering", "Tetrahedral meshes", "Meshes",
                                         "Comparisons"].index)
    assert mode_names(input="mesh") == ["mesh"]
    assert "raymarch" not in mode_names(output="surface")


def test_registration_refuses_duplicates_and_clashing_options(test_mode):
    with pytest.raises(ValueError, match="already registered"):
        register_mode(TEST_MODE)
    clash = SurfaceMode("test-clash", "Clash", "an option named like raymarch's with another meaning",
                        group="Surfaces", origin="ours", input="volume", output="surface",
                        make_filter=shifted_faces, options=(Option("samples", "float", 1.0, "x", unit="mm"),))
    with pytest.raises(ValueError, match="--samples clashes"):
        register_mode(clash)
    assert "test-clash" not in mode_names()


def test_options_are_typed_and_checked():
    raymarch = get_mode("raymarch")
    assert raymarch.resolve_options({"lighting": "scatter", "light_samples": "8"}) == {
        "lighting": "scatter", "samples": None, "light_samples": 8, "jitter": True, "passes": 1}
    with pytest.raises(ValueError, match="--lighting must be one of emission, phong, scatter"):
        raymarch.resolve_options({"lighting": "sun"})
    with pytest.raises(ValueError, match="--light-samples must be a whole number"):
        raymarch.resolve_options({"light_samples": "2.5"})
    with pytest.raises(ValueError, match="--light-samples must be at least 1"):
        raymarch.resolve_options({"light_samples": 0})
    with pytest.raises(ValueError, match="give either a number of slices"):
        get_mode("slicing").resolve_options({"slices": 10, "slice_distance": 1.0})
    assert get_mode("slicing").resolve_options({"slice_distance": "0.5"})["slice_distance"] == 0.5
    with pytest.raises(ValueError, match="--slice-distance must be at least 0.001 mm"):
        get_mode("slicing").resolve_options({"slice_distance": 0})
    option = Option("flag", "bool", False, "a switch")
    assert option.validate("yes") is True and option.validate("off") is False
    with pytest.raises(ValueError, match="--flag must be true or false"):
        option.validate("maybe")
    with pytest.raises(ValueError, match="identifiers"):
        Option("not valid", "int", 1, "x")
