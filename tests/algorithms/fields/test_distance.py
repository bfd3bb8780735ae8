"""Exact band distances, the sign and the propagation of :mod:`algorithms.fields.distance` (source 002, chapter 3):
against brute-force exact distances, analytic spheres and tori, ``vtkImplicitPolyDataDistance`` on real meshes and a
marching-cubes skull, and the voxelisation mask."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.fields.distance import band_distances, exact_distances, signed_distance
from algorithms.fields.voxelise import voxelise

from ._voxelise_shapes import box, octahedron, real_mesh, rotation, sphere, torus

#: Required agreement inside the band, as a fraction of the (smallest) voxel size.
BAND_TOLERANCE = 1e-4


def _bounds(points, pad=0.0):
    low, high = points.min(axis=0) - pad, points.max(axis=0) + pad
    return np.ravel(np.column_stack([low, high]))


def _world(grid, flat):
    k, j, i = np.unravel_index(flat, grid.shape)
    return grid.index_to_world(np.stack([i, j, k], 1).astype(np.float64))


def _rotated_grid(points, spacing, angle=37.0, pad=4.0):
    direction = rotation((1.0, 2.0, 3.0), angle)
    spacing = np.asarray(spacing, dtype=np.float64)
    local = points @ direction
    first = np.floor((local.min(axis=0) - pad) / spacing)
    last = np.ceil((local.max(axis=0) + pad) / spacing)
    return Grid(tuple(int(n) for n in last - first + 1), tuple(spacing), tuple(direction @ (first * spacing)),
                tuple(direction.ravel()))


def _sphere_sdf(x, radius):
    return np.linalg.norm(x, axis=1) - radius


def _torus_sdf(x, ring, tube):
    q = np.hypot(x[:, 0], x[:, 1]) - ring
    return np.hypot(q, x[:, 2]) - tube


def _surface_samples(points, triangles):
    """Points on every triangle (centroid, edge midpoints): how far the mesh strays from the analytic shape."""
    a, b, c = points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]
    return np.concatenate([(a + b + c) / 3, (a + b) / 2, (b + c) / 2, (c + a) / 2])


@pytest.mark.parametrize("kind", ["axis", "anisotropic", "rotated"])
@pytest.mark.parametrize("shape", ["sphere", "torus", "box", "octahedron"])
def test_band_is_exact_against_brute_force(shape, kind):
    points, triangles = {"sphere": lambda: sphere(20.0, around=48, across=24),
                         "torus": lambda: torus(20.0, 7.0, around=48, across=24),
                         "box": lambda: box((-10, -12, -9), (11, 10, 13)),
                         "octahedron": lambda: octahedron((0.3, 0.2, 0.1), 17.0)}[shape]()
    if kind == "axis":
        grid = Grid.around(_bounds(points), voxels=40, padding=4)
    elif kind == "anisotropic":
        grid = Grid.around(_bounds(points), spacing=(1.1, 0.8, 1.6), padding=4)
    else:
        grid = _rotated_grid(points, (1.2, 0.9, 1.4))
    band_mm = 3.0 * max(grid.spacing)
    result = band_distances(points, triangles, grid, band_mm)
    exact, nearest = exact_distances(points, triangles, _world(grid, np.arange(grid.size)))
    exact = exact.reshape(grid.shape)
    inside_band = exact <= band_mm
    assert np.count_nonzero(inside_band) > 2000
    ours = np.sqrt(result.distance2.astype(np.float64))
    error = np.abs(ours[inside_band] - exact[inside_band])
    assert error.max() <= BAND_TOLERANCE * min(grid.spacing), f"max error {error.max():.3g} mm"
    # the band is exactly the voxels within d (up to float32 rounding at the band's edge)
    near_edge = np.abs(exact - band_mm) < 1e-5
    assert np.array_equal(result.in_band[~near_edge], inside_band[~near_edge])
    # the nearest triangle kept per band voxel is a nearest triangle
    kept = result.nearest[inside_band]
    assert kept.min() >= 0
    flat = np.flatnonzero(inside_band.ravel())
    world = _world(grid, flat)
    for t in np.unique(kept)[:50]:  # a sample of triangles: distance to the kept triangle equals the distance
        rows = kept == t
        alone, _ = exact_distances(points, triangles[t:t + 1], world[rows])
        assert np.allclose(alone, exact.ravel()[flat][rows], atol=BAND_TOLERANCE * min(grid.spacing))


def test_box_regions_give_the_same_distances():
    points, triangles = torus(20.0, 7.0, around=40, across=20)
    grid = Grid.around(_bounds(points), voxels=36, padding=3)
    tight = band_distances(points, triangles, grid, 4.0)
    boxes = band_distances(points, triangles, grid, 4.0, regions="box")
    both = tight.in_band & boxes.in_band
    assert np.array_equal(tight.in_band, boxes.in_band)
    assert np.array_equal(tight.distance2[both], boxes.distance2[both])
    assert tight.stats["evaluations"] < boxes.stats["evaluations"]


@pytest.mark.parametrize("shape", ["sphere", "torus"])
def test_signed_band_against_analytic_shapes(shape):
    if shape == "sphere":
        points, triangles = sphere(30.0, around=256, across=128)
        analytic = lambda x: _sphere_sdf(x, 30.0)  # noqa: E731
    else:
        points, triangles = torus(30.0, 10.0, around=256, across=128)
        analytic = lambda x: _torus_sdf(x, 30.0, 10.0)  # noqa: E731
    grid = Grid.around(_bounds(points), voxels=64, padding=4)
    field = signed_distance(points, triangles, grid, band_mm=4.0 * grid.spacing[0])
    mask = voxelise(points, triangles, grid)
    assert np.array_equal(np.signbit(field.values), mask.astype(bool))
    flat = np.flatnonzero(np.abs(field.values.ravel()) < field.band_mm)
    world = _world(grid, flat)
    # the tessellation strays from the analytic surface by at most this much (mm)
    stray = np.abs(analytic(_surface_samples(points, triangles))).max()
    assert stray < 0.02 * grid.spacing[0]
    error = np.abs(field.values.ravel()[flat] - analytic(world))
    assert error.max() <= stray + BAND_TOLERANCE * grid.spacing[0], f"max error {error.max():.3g} mm"
    # outside the band: clamped to +-d
    far = np.abs(analytic(_world(grid, np.arange(grid.size)))) > field.band_mm + stray
    assert np.all(np.abs(field.values.ravel()[far]) == np.float32(field.band_mm))


def _normalised_real(name, size=150.0):
    points, triangles, _ = real_mesh(f"{name}.obj.gz")
    low, high = points.min(axis=0), points.max(axis=0)
    return (points - (low + high) / 2) * (size / (high - low).max()), triangles


def _skull():
    from algorithms.surfaces.marching_cubes import marching_cubes
    from app.samples import sample_path
    from app.io import load_volume

    volume = load_volume(sample_path("ct"))
    mesh = marching_cubes(volume.array, 300.0, spacing=volume.spacing, stride=2)
    return np.asarray(mesh.points, np.float64), np.asarray(mesh.triangles, np.int64)


@pytest.mark.parametrize("name", ["spot", "stanford-bunny", "skull"])
def test_band_against_vtk_implicit_distance(name):
    from algorithms.references.vtk_distance import vtk_implicit_distance

    points, triangles = _skull() if name == "skull" else _normalised_real(name)
    grid = Grid.around(_bounds(points), voxels=96, padding=4)
    band_mm = 0.05 * float(np.ptp(points[:, 2]))
    result = band_distances(points, triangles, grid, band_mm)
    flat = np.flatnonzero(result.in_band.ravel())
    assert flat.size > 10_000
    pick = np.random.default_rng(14).choice(flat, 10_000, replace=False)
    theirs, _ = vtk_implicit_distance((points, triangles), _world(grid, pick))
    ours = np.sqrt(result.distance2.ravel()[pick].astype(np.float64))
    error = np.abs(ours - np.abs(theirs))
    assert error.max() <= BAND_TOLERANCE * min(grid.spacing), f"max error {error.max():.3g} mm ({name})"


def test_sign_is_the_voxelisation_mask_on_a_real_mesh():
    points, triangles = _normalised_real("spot")
    grid = _rotated_grid(points, (1.5, 1.2, 1.8), angle=23.0)
    field = signed_distance(points, triangles, grid, band_mm=3.0, outside="propagate")
    mask = voxelise(points, triangles, grid)
    assert mask.sum() > 1000
    assert np.array_equal(np.signbit(field.values), mask.astype(bool))


@pytest.mark.parametrize("shape", ["torus", "spot"])
def test_propagation_error_is_at_most_005_voxels(shape):
    if shape == "torus":
        points, triangles = torus(20.0, 7.0, around=96, across=48)
    else:
        points, triangles = _normalised_real("spot", size=60.0)
    grid = Grid.around(_bounds(points), voxels=64, padding=8)
    field = signed_distance(points, triangles, grid, band_mm=2.0 * grid.spacing[0], outside="propagate")
    far = np.flatnonzero(np.abs(field.values.ravel()) > field.band_mm)
    pick = np.random.default_rng(5).choice(far, 10_000, replace=False)
    exact, _ = exact_distances(points, triangles, _world(grid, pick))
    error = (np.abs(field.values.ravel()[pick].astype(np.float64)) - exact) / grid.spacing[0]
    assert error.min() > -1e-4  # a propagated value is a distance to a real triangle: never below the true one
    assert error.max() <= 0.05, f"max error {error.max():.4f} voxels"
    assert np.all(field.nearest >= 0)


def test_bad_arguments_are_refused():
    points, triangles = box((0, 0, 0), (1, 1, 1))
    grid = Grid((8, 8, 8), (0.25, 0.25, 0.25), (-0.5, -0.5, -0.5))
    with pytest.raises(ValueError, match="band width"):
        band_distances(points, triangles, grid, 0.0)
    with pytest.raises(ValueError, match="outside"):
        signed_distance(points, triangles, grid, band_mm=1.0, outside="sweep")
    with pytest.raises(ValueError, match="regions"):
        band_distances(points, triangles, grid, 1.0, regions="ball")
    with pytest.raises(ValueError, match="no triangles"):
        signed_distance(points, np.empty((0, 3), np.int64), grid, band_mm=1.0)
    with pytest.raises(ValueError, match="point indices"):
        signed_distance(points, triangles + 100, grid, band_mm=1.0)
