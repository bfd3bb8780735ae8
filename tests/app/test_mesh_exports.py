"""Exports that cannot lie (issue 17) and long post-processing that shows progress and stops (issue 20).

- an isovalue outside the data's range, or one that gives no surface, is a one-line error and nothing is written,
  for ``mesh`` and for ``render`` of a surface mode;
- ``--close-edges --decimate 0.5`` keeps the CT phantom's skull watertight; a decimation that would open a closed
  surface is refused; ``volume_mm3`` only for watertight, outward meshes;
- a surface over the size limit needs ``--force`` (the window catches :class:`MeshTooLargeError`), counted before
  it is extracted;
- clean-up, validation and writing report progress and stop on cancellation, leaving nothing behind.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from algorithms.common.progress import OperationCancelled
from algorithms.datasets.volumes import sphere_field
from app import mesh_cleanup, meshing
from app.io.errors import FileExistsRefusal
from app.mesh_cleanup import Cleanup
from app.datasets import ct_head_phantom
from app.meshing import EmptySurfaceError, MeshTooLargeError, export_mesh, surface_for_export, write_export
from app.volume import Volume


def voxelscope(*args):
    return subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def one_line_error(process) -> str:
    assert process.returncode == 1, process.stderr
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("voxelscope: error: "), process.stderr
    assert "Traceback" not in process.stderr
    return lines[0]


@pytest.fixture(scope="module")
def small_ct():
    volume = ct_head_phantom((40, 96, 96), (2.4, 2.4, 4.0))
    volume.metadata["source_path"] = "/data/head.nii.gz"
    return volume


# --------------------------------------------------------------------------------------------------------------
# Isovalues that give no surface
# --------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("iso, why", [(99999, "above the largest value"), (-5000, "at or below the smallest value"),
                                      (-1000, "at or below the smallest value")])
def test_mesh_with_an_isovalue_outside_the_range_writes_nothing(tmp_path, iso, why):
    line = one_line_error(voxelscope("mesh", "sample", "--iso", iso, "-o", tmp_path / "skull.stl"))
    assert f"ct_forbild_head.nii.gz: no surface at {iso} HU, which is {why}" in line
    assert "the values run from -1000 to 800 HU" in line and "choose an isovalue" in line
    assert list(tmp_path.iterdir()) == []


def test_mesh_at_the_maximum_has_no_area_and_writes_nothing(tmp_path):
    # In the egg phantom only single samples reach its maximum, 1526 HU: flying edges makes triangles there, all of
    # them collapsed to points.
    from app.datasets import egg_head_phantom
    from app.io import save_volume

    (tmp_path / "in").mkdir()
    egg = save_volume(egg_head_phantom(), tmp_path / "in" / "egg.nii.gz")
    (tmp_path / "out").mkdir()
    line = one_line_error(voxelscope("mesh", egg, "--iso", 1526, "-o", tmp_path / "out" / "top.ply"))
    assert "the surface at 1526 HU has no area" in line
    assert list((tmp_path / "out").iterdir()) == []


@pytest.mark.parametrize("mode, iso", [("flying-edges", 99999), ("marching-cubes", 1526), ("flying-edges", 801),
                                       ("marching-cubes-vs-flying-edges", 2000)])
def test_render_of_an_empty_surface_writes_nothing(tmp_path, mode, iso):
    line = one_line_error(voxelscope("render", "sample", "--mode", mode, "--iso", iso, "-o", tmp_path / "x.png",
                                     "--size", 64, 64))
    assert "ct_forbild_head.nii.gz: no surface" in line and "800 HU" in line
    assert list(tmp_path.iterdir()) == []


def test_empty_surfaces_through_the_api(small_ct, tmp_path):
    with pytest.raises(EmptySurfaceError, match=r"^head\.nii\.gz: no surface at 2000 HU"):
        export_mesh(small_ct, tmp_path / "a.stl", method="marching-cubes", iso=2000.0)
    with pytest.raises(EmptySurfaceError, match="finite"):
        surface_for_export(small_ct, method="flying-edges", iso=float("nan"))
    # Capped at the edges a surface needs only iso <= maximum: everything inside is a closed box.
    box = surface_for_export(small_ct, method="marching-cubes", iso=-1000.0, close_edges=True)
    assert mesh_cleanup.validity_report(box.polydata).watertight
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------------------------------
# Decimation and enclosed volume
# --------------------------------------------------------------------------------------------------------------
def test_close_edges_and_decimation_keep_the_skull_watertight(tmp_path):
    reports = {}
    for name, extra in (("full", ()), ("half", ("--decimate", 0.5))):
        out = tmp_path / f"{name}.stl"
        process = voxelscope("mesh", "sample", "--close-edges", *extra, "-o", out, "--json")
        assert process.returncode == 0, process.stderr
        reports[name] = json.loads(process.stdout)
    full, half = reports["full"]["validity"], reports["half"]["validity"]
    assert full["watertight"] and full["manifold"] and full["outward_normals"]
    assert half["watertight"] and half["manifold"] and half["outward_normals"]
    assert half["triangles"] == pytest.approx(0.5 * full["triangles"], rel=0.02)
    assert half["volume_mm3"] == pytest.approx(full["volume_mm3"], rel=0.005)
    sidecar = json.loads((tmp_path / "half.stl.json").read_text())
    assert sidecar["validity"]["watertight"] and sidecar["parameters"]["decimate"] == 0.5
    assert sidecar["parameters"]["decimation_achieved"] == pytest.approx(0.5, abs=0.02)
    assert "decimation" in sidecar["parameters"]


def test_decimation_that_would_open_a_closed_surface_is_refused(monkeypatch):
    sphere = meshing.extract_surface(Volume(sphere_field((24, 24, 24), 8.0).astype(np.float32)), "marching-cubes",
                                     0.0).polydata
    results = iter([True, False, False])  # the input is closed; both decimations open it
    monkeypatch.setattr(mesh_cleanup, "_watertight", lambda polydata: next(results))
    with pytest.raises(mesh_cleanup.DecimationError) as caught:
        mesh_cleanup.decimate(sphere, 0.5)
    message = str(caught.value)
    assert "\n" not in message and "would open this closed surface" in message and "smaller fraction" in message


def test_decimating_a_closed_surface_keeps_it_closed_or_says_how():
    sphere = meshing.extract_surface(Volume(sphere_field((24, 24, 24), 8.0).astype(np.float32)), "marching-cubes",
                                     0.0).polydata
    notes = {}
    result = mesh_cleanup.decimate(sphere, 0.6, notes=notes)
    assert mesh_cleanup.validity_report(result).watertight
    assert notes["decimation"].startswith(("quadric", "topology-preserving"))
    assert notes["decimation_achieved"] == pytest.approx(0.6, abs=0.05)


def test_volume_only_for_watertight_outward_meshes(small_ct, tmp_path):
    from app.io import save_volume

    cut = save_volume(small_ct, tmp_path / "cut.nii.gz")  # 160 mm of slices: the skull leaves at both ends
    process = voxelscope("mesh", cut, "--method", "marching-cubes", "-o", tmp_path / "open.obj", "--json")
    assert process.returncode == 0, process.stderr
    validity = json.loads(process.stdout)["validity"]
    assert not validity["watertight"] and validity["volume_mm3"] is None  # the skull is open at the last slice
    assert json.loads((tmp_path / "open.obj.json").read_text())["validity"]["volume_mm3"] is None


# --------------------------------------------------------------------------------------------------------------
# Size limit
# --------------------------------------------------------------------------------------------------------------
def test_too_large_is_refused_before_extraction(small_ct, monkeypatch):
    from app.modes import get_mode

    mode = get_mode("flying-edges")
    estimate = mode.estimate_triangles(small_ct, 300.0)
    actual = mode.extract(small_ct, 300.0).stats["triangles"]
    assert abs(estimate - actual) <= 0.01 * actual  # our counting pass, VTK's case table

    def no_extraction(*args, **kwargs):
        raise AssertionError("extracted although the count was over the limit")

    monkeypatch.setattr(type(mode), "extract", no_extraction)
    with pytest.raises(MeshTooLargeError) as caught:
        surface_for_export(small_ct, method="flying-edges", iso=300.0, max_triangles=1000)
    error = caught.value
    assert error.triangles == estimate and error.limit == 1000 and isinstance(error, ValueError)
    assert "would have about" in str(error) and "--force" in str(error) and "\n" not in str(error)


def test_voxel_face_count_is_exact(small_ct):
    from app.modes import get_mode

    for name in ("voxel-faces", "tower"):
        mode = get_mode(name)
        assert mode.estimate_triangles(small_ct, 300.0) == mode.extract(small_ct, 300.0).stats["triangles"]
    # Small grids cannot exceed the limit: no count is made.
    assert get_mode("voxel-faces").estimate_triangles(small_ct, 300.0, limit=20_000_000) is None


def test_command_line_needs_force_for_a_large_mesh(tmp_path, monkeypatch, capsys):
    from app.cli import main

    monkeypatch.setattr(meshing, "MAX_TRIANGLES", 10_000)
    out = tmp_path / "big.stl"
    assert main(["mesh", "sample", "-o", str(out)]) == 1
    error = capsys.readouterr().err
    assert "triangles, more than the 10,000 an export makes without asking" in error
    assert "--force" in error and len(error.strip().splitlines()) == 1 and not out.exists()
    assert main(["mesh", "sample", "-o", str(out), "--force"]) == 0
    assert out.exists()


def test_a_given_surface_over_the_limit_is_refused(small_ct, tmp_path, monkeypatch):
    """The window passes the surface its view shows: its size is known, and checked before any post-processing."""
    result = meshing.extract_surface(small_ct, "marching-cubes", 300.0)
    triangles = result.stats["triangles"]
    monkeypatch.setattr(meshing, "MAX_TRIANGLES", triangles - 1)
    with pytest.raises(MeshTooLargeError, match=rf"has {triangles:,} triangles, more than the {triangles - 1:,}"):
        export_mesh(small_ct, tmp_path / "a.stl", method="marching-cubes", iso=300.0, result=result)
    assert list(tmp_path.iterdir()) == []
    export = export_mesh(small_ct, tmp_path / "a.stl", method="marching-cubes", iso=300.0, result=result,
                         allow_large=True)
    assert export.paths == [tmp_path / "a.stl", tmp_path / "a.stl.json"]


# --------------------------------------------------------------------------------------------------------------
# Progress and cancellation
# --------------------------------------------------------------------------------------------------------------
def test_post_processing_reports_progress(small_ct, tmp_path):
    seen = []
    surface = surface_for_export(small_ct, method="flying-edges", iso=300.0, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0
    steps = []
    write_export(surface, tmp_path / "a.ply", cleanup=Cleanup(largest_component=True, smooth_iterations=5,
                                                                  decimate=0.3), progress=steps.append)
    assert steps == sorted(steps) and steps[-1] == 1.0
    # Clean-up (0-0.4), validation (0.4-0.8) and writing (0.8-1; once per block of triangles) each report inside
    # their share.
    for low, high in ((0.0, 0.4), (0.4, 0.8), (0.8, 1.0)):
        assert any(low < value < high for value in steps), (low, high, steps)


@pytest.mark.parametrize("stop_at", [0.2, 0.5, 0.9])
def test_cancelling_post_processing_leaves_nothing(small_ct, tmp_path, stop_at):
    surface = surface_for_export(small_ct, method="flying-edges", iso=300.0)

    def cancel(fraction):
        if fraction > stop_at:
            raise OperationCancelled("cancelled")

    with pytest.raises(OperationCancelled):
        write_export(surface, tmp_path / "a.stl", cleanup=Cleanup(smooth_iterations=5, decimate=0.3),
                     progress=cancel)
    assert list(tmp_path.iterdir()) == []


def test_validity_report_is_cancelled_inside_the_nesting_test():
    """Many closed pieces inside one (noise in a skull): the nesting test reports progress piece by piece and stops
    when asked."""
    field = sphere_field((60, 60, 60), 25.0)  # a ball (positive inside)...
    k, j, i = np.ogrid[:60, :60, :60]
    for centre in np.random.default_rng(0).integers(18, 42, size=(40, 3)):  # ...with bubbles in it
        field = np.minimum(field, np.sqrt((k - centre[0]) ** 2 + (j - centre[1]) ** 2 + (i - centre[2]) ** 2) - 1.6)
    polydata = meshing.extract_surface(Volume(field.astype(np.float32)), "marching-cubes", 0.0).polydata
    seen = []
    report = mesh_cleanup.validity_report(polydata, progress=seen.append)
    assert report.watertight and report.outward_normals and report.components > 10
    assert seen == sorted(seen) and seen[-1] == 1.0
    nesting = [value for value in seen if 0.75 < value < 1.0]  # the nesting test's share
    assert len(nesting) >= 2
    stopped = []

    def cancel(fraction):
        if fraction > 0.75:
            stopped.append(fraction)
            raise OperationCancelled("cancelled")

    with pytest.raises(OperationCancelled):
        mesh_cleanup.validity_report(polydata, progress=cancel)
    assert stopped == [nesting[0]]  # stopped at its first report inside the nesting test


def test_export_checks_targets_before_any_work(small_ct, tmp_path, monkeypatch):
    (tmp_path / "a.stl.json").write_text("{}")

    def no_work(*args, **kwargs):
        raise AssertionError("extracted although the sidecar exists")

    monkeypatch.setattr(meshing, "surface_for_export", no_work)
    with pytest.raises(FileExistsRefusal, match="a.stl.json already exists"):
        export_mesh(small_ct, tmp_path / "a.stl", method="flying-edges", iso=300.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.stl.json"]
    assert Path(tmp_path / "a.stl.json").read_text() == "{}"
