"""Mesh clean-up on surfaces with known answers: a terraced sphere, two spheres, a sphere cut open."""

from __future__ import annotations

import numpy as np
import pytest
from vtkmodules.util import numpy_support

from algorithms import compare as sc
from algorithms.surfaces.marching_cubes import marching_cubes
from app import mesh_cleanup
from app.datasets import sphere_field

RADIUS = 10.0
SPHERE_AREA = 4 * np.pi * RADIUS**2
SPHERE_VOLUME = 4 / 3 * np.pi * RADIUS**3


@pytest.fixture(scope="module")
def terraced_sphere():
    """The surface of a voxelised ball (isovalue 0.5 on a 0/1 mask): staircase artefacts, with normals."""
    mask = (sphere_field((30, 30, 30), RADIUS) >= 0).astype(np.uint8)
    return marching_cubes(mask, 0.5, normals=True).to_polydata()


@pytest.fixture(scope="module")
def two_spheres():
    big = sphere_field((30, 60, 30), RADIUS)
    small = np.roll(sphere_field((30, 60, 30), 4.0), 20, axis=1)  # centred 20 voxels further along j
    return marching_cubes(np.maximum(big, small), 0.0).to_polydata()


@pytest.fixture(scope="module")
def open_sphere():
    """A sphere of radius 10 in a volume 16 samples high: cut by both k faces, two round holes of radius 6."""
    return marching_cubes(sphere_field((17, 30, 30), RADIUS), 0.0).to_polydata()


def radii(polydata, centre):
    return np.linalg.norm(sc.surface_arrays(polydata)[0] - centre, axis=1)


def normals_of(polydata):
    return numpy_support.vtk_to_numpy(polydata.GetPointData().GetNormals())


def test_smooth_removes_the_staircase_and_keeps_the_volume(terraced_sphere):
    centre = np.full(3, 14.5)
    smoothed = mesh_cleanup.smooth(terraced_sphere, iterations=20, passband=0.1)
    assert sc.surface_area(terraced_sphere) > 1.07 * SPHERE_AREA  # the staircase adds area
    assert sc.surface_area(smoothed) == pytest.approx(SPHERE_AREA, rel=0.02)
    assert sc.enclosed_volume(smoothed) == pytest.approx(sc.enclosed_volume(terraced_sphere), rel=0.005)
    assert radii(smoothed, centre).std() < 0.6 * radii(terraced_sphere, centre).std()
    assert smoothed.GetNumberOfCells() == terraced_sphere.GetNumberOfCells()
    # Point normals were recomputed for the new shape and still point outward.
    normals = normals_of(smoothed)
    outward = sc.surface_arrays(smoothed)[0] - centre
    assert np.all((normals * outward).sum(axis=1) > 0)
    assert not np.allclose(normals, normals_of(terraced_sphere))
    assert terraced_sphere.GetPointData().GetNormals() is not None  # the input keeps its own


def test_decimate_keeps_volume_and_topology(terraced_sphere):
    smoothed = mesh_cleanup.smooth(terraced_sphere)
    decimated = mesh_cleanup.decimate(smoothed, 0.75)
    ratio = decimated.GetNumberOfCells() / smoothed.GetNumberOfCells()
    assert ratio == pytest.approx(0.25, abs=0.03)
    assert sc.enclosed_volume(decimated) == pytest.approx(sc.enclosed_volume(smoothed), rel=0.01)
    report = mesh_cleanup.validity_report(decimated)
    assert report.watertight and report.manifold and report.outward_normals
    assert normals_of(decimated).shape == (decimated.GetNumberOfPoints(), 3)
    assert mesh_cleanup.decimate(smoothed, 0.0).GetNumberOfCells() == smoothed.GetNumberOfCells()


def test_keep_largest_component(two_spheres):
    assert sc.connected_components(two_spheres) == 2
    largest = mesh_cleanup.keep_largest_component(two_spheres)
    assert sc.connected_components(largest) == 1
    points, triangles = sc.surface_arrays(largest)
    assert len(np.unique(triangles)) == len(points)  # the other sphere's points are gone
    assert sc.enclosed_volume(largest) == pytest.approx(SPHERE_VOLUME, rel=0.01)


def test_fill_small_holes(open_sphere):
    before = mesh_cleanup.validity_report(open_sphere)
    assert not before.watertight and before.manifold
    # The holes have radius 6 mm; VTK's bounding-sphere estimate of their rims is 8.8 mm (see the docstring).
    assert not mesh_cleanup.validity_report(mesh_cleanup.fill_small_holes(open_sphere, 8.0)).watertight
    filled = mesh_cleanup.fill_small_holes(open_sphere, 9.0)
    report = mesh_cleanup.validity_report(filled)
    assert report.watertight and report.manifold and report.outward_normals
    # The caps close two spherical caps off the ball: volume of a sphere of radius 10 cut at |z| = 8.
    cap = np.pi * 2.0**2 * (3 * RADIUS - 2.0) / 3
    assert report.volume_mm3 == pytest.approx(SPHERE_VOLUME - 2 * cap, rel=0.01)
    assert filled.GetPointData().GetNormals() is not None


def test_validity_report(terraced_sphere, two_spheres, open_sphere):
    report = mesh_cleanup.validity_report(terraced_sphere)
    assert report.watertight and report.manifold and report.outward_normals and report.components == 1
    assert report.points == terraced_sphere.GetNumberOfPoints()
    assert report.triangles == terraced_sphere.GetNumberOfCells()
    assert report.area_mm2 == pytest.approx(sc.surface_area(terraced_sphere))
    assert report.volume_mm3 == pytest.approx(SPHERE_VOLUME, rel=0.01)
    assert set(report.as_dict()) == {"watertight", "manifold", "outward_normals", "components", "points",
                                     "triangles", "area_mm2", "volume_mm3"}
    assert "watertight, manifold, outward; 1 piece(s)" in report.summary()
    assert mesh_cleanup.validity_report(two_spheres).components == 2
    open_report = mesh_cleanup.validity_report(open_sphere)
    assert "not watertight" in open_report.summary()
    # An open or inside-out surface encloses no volume: the report gives none rather than a guess.
    assert open_report.volume_mm3 is None and "no enclosed volume" in open_report.summary()
    inward = marching_cubes(-sphere_field((30, 30, 30), RADIUS), 0.0)  # the outside of a ball is the solid
    inward_report = mesh_cleanup.validity_report(inward.to_polydata())
    assert inward_report.watertight and not inward_report.outward_normals and inward_report.volume_mm3 is None


def test_apply_runs_the_chosen_steps_in_order(two_spheres):
    assert mesh_cleanup.apply(two_spheres) is two_spheres
    seen = []
    cleaned = mesh_cleanup.apply(two_spheres, smooth_iterations=10, decimate=0.5, largest_component=True,
                                 fill_holes_mm=2.0, progress=seen.append)
    assert sc.connected_components(cleaned) == 1
    largest = mesh_cleanup.keep_largest_component(two_spheres)
    assert cleaned.GetNumberOfCells() == pytest.approx(0.5 * largest.GetNumberOfCells(), rel=0.05)
    assert seen == sorted(seen) and seen[-1] == 1.0


@pytest.mark.parametrize(
    "step",
    [
        lambda surface, p: mesh_cleanup.smooth(surface, progress=p),
        lambda surface, p: mesh_cleanup.decimate(surface, 0.5, progress=p),
        lambda surface, p: mesh_cleanup.keep_largest_component(surface, progress=p),
        lambda surface, p: mesh_cleanup.fill_small_holes(surface, 2.0, progress=p),
    ],
)
def test_each_step_reports_progress(two_spheres, step):
    seen = []
    step(two_spheres, seen.append)
    assert seen and seen == sorted(seen) and seen[-1] == pytest.approx(1.0)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda s: mesh_cleanup.smooth("not a surface"), "expected a vtkPolyData"),
        (lambda s: mesh_cleanup.validity_report(np.zeros((3, 3))), "expected a vtkPolyData"),
        (lambda s: mesh_cleanup.smooth(s, iterations=0), "iterations"),
        (lambda s: mesh_cleanup.smooth(s, iterations=2.5), "iterations"),
        (lambda s: mesh_cleanup.smooth(s, iterations=True), "iterations"),
        (lambda s: mesh_cleanup.smooth(s, passband=0.0), "passband"),
        (lambda s: mesh_cleanup.smooth(s, passband=2.5), "passband"),
        (lambda s: mesh_cleanup.smooth(s, passband=float("nan")), "passband"),
        (lambda s: mesh_cleanup.decimate(s, -0.1), "target_reduction"),
        (lambda s: mesh_cleanup.decimate(s, 1.0), "target_reduction"),
        (lambda s: mesh_cleanup.fill_small_holes(s, 0.0), "max_hole_size_mm"),
        (lambda s: mesh_cleanup.fill_small_holes(s, -2.0), "max_hole_size_mm"),
        (lambda s: mesh_cleanup.fill_small_holes(s, float("inf")), "max_hole_size_mm"),
        (lambda s: mesh_cleanup.apply(s, decimate=1.5), "target_reduction"),
    ],
)
def test_value_errors(terraced_sphere, call, message):
    with pytest.raises(ValueError, match=message):
        call(terraced_sphere)
