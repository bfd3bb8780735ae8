"""Mesh voxelisation: exact decisions where rows meet vertices and edges, analytic volumes, nesting, parity against
the exact ray test, errors, progress and cancellation."""

from __future__ import annotations

import re

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.common.progress import OperationCancelled
from algorithms.fields.voxelise import voxelise, voxelise_with_report

from ._voxelise_shapes import box, flipped, joined, octahedron, real_mesh, rotation, sphere, torus


def _ijk(grid):
    k, j, i = np.indices(grid.shape)
    return i, j, k


def _on_grid(grid, index_points):
    """World points of index coordinates on ``grid``."""
    return grid.index_to_world(np.asarray(index_points, dtype=np.float64))


GRIDS = {
    "unit": Grid((24, 22, 20)),
    "anisotropic": Grid((24, 22, 20), spacing=(0.5, 0.5, 2.0), origin=(-3.25, 7.5, 100.0)),
    "rotated": Grid((24, 22, 20), spacing=(0.7, 0.9, 1.3), origin=(12.3, -4.1, 0.7),
                    direction=tuple(rotation((1, 2, 3), 37).ravel())),
    "left-handed": Grid((24, 22, 20), spacing=(1.0, 1.0, 1.0), direction=(-1, 0, 0, 0, 1, 0, 0, 0, 1)),
}


# -- exactness where rows pass through vertices and edges ----------------------------------------------------------
@pytest.mark.parametrize("name", list(GRIDS))
def test_box_with_corners_on_voxel_centres_is_exact(name):
    """Faces through voxel centres, rows along faces and through every edge and corner: the answer is the
    perturbed-centre rule exactly (a centre on a face counts when moving it by (+e', +e, +e^2) along (i, j, k)
    takes it inside), which makes the voxel count exactly the box's volume in voxels."""
    grid = GRIDS[name]
    low, high = np.array([3, 4, 5]), np.array([17, 15, 12])
    corners_index, triangles = box(low, high)
    mask = voxelise(_on_grid(grid, corners_index), triangles, grid)
    i, j, k = _ijk(grid)
    expected = ((i >= low[0]) & (i < high[0]) & (j >= low[1]) & (j < high[1]) & (k >= low[2]) & (k < high[2]))
    assert np.array_equal(mask, expected.astype(np.uint8))
    assert mask.sum() == np.prod(high - low)


@pytest.mark.parametrize("name", list(GRIDS))
def test_box_with_faces_between_voxel_centres_is_exact(name):
    grid = GRIDS[name]
    low, high = np.array([2.5, 3.5, 1.5]), np.array([15.5, 9.5, 13.5])
    corners_index, triangles = box(low, high)
    mask = voxelise(_on_grid(grid, corners_index), triangles, grid)
    i, j, k = _ijk(grid)
    expected = (i > low[0]) & (i < high[0]) & (j > low[1]) & (j < high[1]) & (k > low[2]) & (k < high[2])
    assert np.array_equal(mask, expected.astype(np.uint8))


@pytest.mark.parametrize("name", list(GRIDS))
@pytest.mark.parametrize("radius", [1, 4, 7])
def test_octahedron_with_vertices_on_voxel_centres_is_exact(name, radius):
    """Rows through all six vertices and along the edges; centres on the faces decided by the perturbation:
    a centre with f = |dx| + |dy| + |dz| = r is inside exactly when moving it by +e' along i lowers f, i.e. dx < 0."""
    grid = GRIDS[name]
    centre = np.array([11, 10, 9])
    corners_index, triangles = octahedron(centre, radius)
    mask = voxelise(_on_grid(grid, corners_index), triangles, grid)
    i, j, k = _ijk(grid)
    dx, dy, dz = i - centre[0], j - centre[1], k - centre[2]
    f = np.abs(dx) + np.abs(dy) + np.abs(dz)
    expected = (f < radius) | ((f == radius) & (dx < 0))
    assert np.array_equal(mask, expected.astype(np.uint8))


def test_voxel_surface_of_a_random_solid_gives_the_solid_back():
    """The visible-face surface of random voxels (closed, non-manifold where voxels meet at an edge) voxelised on
    its own grid: every row passes through the centre of a face, exactly on a diagonal of its two triangles."""
    from algorithms.surfaces.voxel_faces import voxel_faces

    rng = np.random.default_rng(7)
    solid = rng.random((14, 15, 16)) < 0.35
    solid[0], solid[-1], solid[:, 0], solid[:, -1], solid[:, :, 0], solid[:, :, -1] = (False,) * 6
    spacing, origin = (0.5, 0.75, 1.25), (3.0, -2.0, 10.0)
    faces = voxel_faces(solid, spacing=spacing, origin=origin)
    points, inverse = np.unique(faces.points.astype(np.float64), axis=0, return_inverse=True)
    triangles = inverse.reshape(-1)[faces.triangles]
    grid = Grid(solid.shape[::-1], spacing, origin)
    assert np.array_equal(voxelise(points, triangles, grid), solid.astype(np.uint8))


# -- analytic volumes --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", ["sphere", "torus"])
def test_volume_at_256_is_within_a_tenth_of_a_percent_of_the_analytic_volume(shape):
    if shape == "sphere":
        points, triangles = sphere(20.0, around=720, across=360)
        analytic = 4.0 / 3.0 * np.pi * 20.0 ** 3
    else:
        points, triangles = torus(20.0, 7.0, around=720, across=360)
        analytic = 2 * np.pi ** 2 * 20.0 * 7.0 ** 2
    low, high = points.min(axis=0), points.max(axis=0)
    grid = Grid.around(np.ravel(np.column_stack([low, high])), voxels=256)
    mask = voxelise(points, triangles, grid)
    volume = mask.sum(dtype=np.int64) * grid.voxel_volume
    assert abs(volume - analytic) / analytic < 1e-3, (volume, analytic)


# -- several shells -----------------------------------------------------------------------------------------------
def test_nested_shells_cavities_and_touching_pieces_by_parity():
    grid = Grid((64, 64, 64), spacing=(1.0, 1.0, 1.0), origin=(-32.0, -32.0, -32.0))
    i, j, k = _ijk(grid)
    world = grid.index_to_world(np.stack([i, j, k], -1).reshape(-1, 3)).reshape(grid.shape + (3,))
    r = np.linalg.norm(world, axis=-1)
    outer, cavity, island = (sphere(rad, around=256, across=128) for rad in (28.3, 20.2, 10.1))
    # orientation does not matter for parity: the cavity's wall facing in or out gives the same shell
    for shells in ((outer, flipped(cavity), island), (outer, cavity, island)):
        mask = voxelise(*joined(*shells), grid)
        expected_far = (r < 27.5) & ((r > 21.0) | (r < 9.5))
        decided = (np.abs(r - 28.3) > 1) & (np.abs(r - 20.2) > 1) & (np.abs(r - 10.1) > 1)
        assert np.array_equal(mask[decided], expected_far[decided].astype(np.uint8))
    # two boxes touching along a face (separate vertices): the shared face's crossings cancel
    touching = joined(box((-20.5, -5.5, -5.5), (0.5, 5.5, 5.5)), box((0.5, -5.5, -5.5), (20.5, 5.5, 5.5)))
    mask = voxelise(*touching, grid)
    assert mask.sum() == 41 * 11 * 11
    assert np.all(mask[32 - 5:32 + 6, 32 - 5:32 + 6, 32 - 20:32 + 21] == 1)


def test_matches_the_exact_ray_test_at_voxel_centres(rng):
    """Our rows and the comparison toolkit's ray test use the same simulation of simplicity: same inside set."""
    from algorithms.compare.topology import ray_crossings

    points, triangles, _ = real_mesh("spot.obj.gz")
    low, high = points.min(axis=0), points.max(axis=0)
    grid = Grid.around(np.ravel(np.column_stack([low, high])), voxels=40)
    mask = voxelise(points, triangles, grid)
    chosen = rng.choice(mask.size, 3000, replace=False)
    k, rest = np.divmod(chosen, grid.shape[1] * grid.shape[2])
    j, i = np.divmod(rest, grid.shape[2])
    parity = ray_crossings(points, triangles, grid.index_to_world(np.stack([i, j, k], 1))) % 2
    assert np.array_equal(mask.reshape(-1)[chosen], parity.astype(np.uint8))
    assert 0 < mask.sum() < mask.size


def test_mesh_partly_or_wholly_outside_the_grid():
    """Crossings left of the grid still count (a row that enters the mesh before the grid starts is inside from
    its first voxel); a mesh beside the grid gives an empty mask."""
    grid = Grid((10, 10, 10))
    points, triangles = box((-50.5, 2.5, 2.5), (5.5, 6.5, 6.5))
    mask = voxelise(points, triangles, grid)
    assert mask.sum() == 6 * 4 * 4 and np.all(mask[3:7, 3:7, :6] == 1)
    points, triangles = box((20.5, 2.5, 2.5), (25.5, 6.5, 6.5))
    assert voxelise(points, triangles, grid).sum() == 0


def test_report_counts_crossings_and_names_the_rule():
    points, triangles = box((1.5, 1.5, 1.5), (5.5, 4.5, 3.5))
    mask, report = voxelise_with_report(points, triangles, Grid((8, 8, 8)))
    assert report.rule == "parity" and report.caps == 0
    assert report.crossings == 2 * 3 * 2  # two per row through the box (3 rows in y, 2 in z)
    assert mask.sum() == 4 * 3 * 2


# -- errors, progress, cancellation ------------------------------------------------------------------------------
@pytest.mark.parametrize("points, triangles, grid, inside, message", [
    (np.zeros((3, 2)), [[0, 1, 2]], Grid((4, 4, 4)), "parity", "(n, 3)"),
    ([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], [[0, 1, 2]], Grid((4, 4, 4)), "parity", "NaN"),
    (np.zeros((3, 3)), [[0, 1, 3]], Grid((4, 4, 4)), "parity", "point indices in [0, 3)"),
    (np.zeros((3, 3)), [[0.0, 1.0, 2.0]], Grid((4, 4, 4)), "parity", "point indices"),
    (np.zeros((3, 3)), [[0, 1, 2]], (4, 4, 4), "parity", "Grid"),
    (np.zeros((3, 3)), [[0, 1, 2]], Grid((4, 4, 4)), "even-odd", "parity, winding"),
])
def test_bad_input_is_a_value_error_saying_what_is_wrong(points, triangles, grid, inside, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        voxelise(points, triangles, grid, inside=inside)


def test_no_triangles_gives_an_empty_mask():
    mask = voxelise(np.zeros((0, 3)), np.zeros((0, 3), dtype=int), Grid((3, 4, 5)))
    assert mask.shape == (5, 4, 3) and mask.dtype == np.uint8 and mask.sum() == 0


def test_progress_rises_to_one_and_cancelling_stops_the_work():
    points, triangles = sphere(20.0, around=64, across=32)
    grid = Grid.around((-20, 20, -20, 20, -20, 20), voxels=200)
    seen = []
    voxelise(points, triangles, grid, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) > 3

    def cancel(fraction):
        if fraction > 0.2:
            raise OperationCancelled("stop")

    with pytest.raises(OperationCancelled):
        voxelise(points, triangles, grid, progress=cancel)
