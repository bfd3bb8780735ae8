"""The winding-number rule: generalised winding numbers (exact, tree), fans over holes, agreement with parity on
closed meshes, open and self-intersecting meshes, the bunny with holes."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.fields.voxelise import voxelise, voxelise_with_report
from algorithms.fields.winding import WindingTree, boundary_caps, solid_angle_winding

from ._voxelise_shapes import box, flipped, joined, real_mesh, sphere, torus


def _grid_around(points, voxels, padding=2):
    low, high = points.min(axis=0), points.max(axis=0)
    return Grid.around(np.ravel(np.column_stack([low, high])), voxels=voxels, padding=padding)


def _centres(grid):
    k, j, i = np.indices(grid.shape)
    return grid.index_to_world(np.stack([i, j, k], -1).reshape(-1, 3))


# -- winding numbers ----------------------------------------------------------------------------------------------
def test_exact_winding_number_is_one_inside_zero_outside_a_closed_surface():
    points, triangles = sphere(5.0, around=32, across=16)
    w = solid_angle_winding(points, triangles, [[0, 0, 0], [1, 2, -1], [9, 0, 0], [0, -30, 4]])
    assert np.allclose(w, [1, 1, 0, 0], atol=1e-9)
    assert np.allclose(solid_angle_winding(*flipped((points, triangles)), [[0, 0, 0]]), -1, atol=1e-9)


def test_half_sphere_has_winding_number_one_half_at_its_centre():
    points, triangles = sphere(5.0, around=64, across=32)
    upper = triangles[np.all(points[triangles][:, :, 2] >= -1e-9, axis=1)]
    assert np.isclose(solid_angle_winding(points, upper, [[0, 0, 0]])[0], 0.5, atol=1e-9)


@pytest.mark.parametrize("beta", [2.0, 3.0])
def test_tree_agrees_with_the_exact_sum(rng, beta):
    points, triangles, _ = real_mesh("stanford-bunny.obj.gz")
    low, high = points.min(axis=0), points.max(axis=0)
    queries = low - 0.1 * (high - low) + 1.2 * (high - low) * rng.random((400, 3))
    exact = solid_angle_winding(points, triangles, queries)
    tree = WindingTree.build(points, triangles)
    fast = tree.winding_numbers(queries, beta=beta)
    tolerance = {2.0: 0.05, 3.0: 0.02}[beta]
    assert np.abs(fast - exact).max() < tolerance
    assert np.median(np.abs(fast - exact)) < tolerance / 10
    with pytest.raises(ValueError, match="beta"):
        tree.winding_numbers(queries, beta=1.0)


def test_fans_close_every_hole():
    from algorithms.compare.topology import edge_manifoldness

    points, triangles, _ = real_mesh("stanford-bunny.obj.gz")
    caps = boundary_caps(points, triangles)
    closed = np.concatenate([triangles, caps.triangles])
    report = edge_manifoldness(caps.points, closed)
    assert report.boundary_edges == 0 and report.odd_edges == 0
    assert caps.edges == edge_manifoldness(points, triangles).boundary_edges == 223
    assert caps.count == 5  # the five holes of the scanned base
    assert boundary_caps(*sphere(3.0, around=16, across=8)).count == 0


# -- the winding rule on grids ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, overlapping", [("spot.obj.gz", 0), ("fandisk.obj.gz", 0), ("cow.obj.gz", 8)])
def test_winding_and_parity_agree_voxel_for_voxel_on_closed_meshes(name, overlapping):
    """They differ only where the surface passes through itself (the cow's: winding number 2 at 8 voxels), where
    parity counts an even number of crossings and the winding rule sees two layers of solid."""
    points, triangles, _ = real_mesh(name)
    grid = _grid_around(points, 96)
    parity = voxelise(points, triangles, grid)
    winding, report = voxelise_with_report(points, triangles, grid, inside="winding")
    assert report.caps == 0 and report.rule == "winding"
    differ = np.argwhere(parity != winding)
    assert len(differ) == overlapping
    if overlapping:
        exact = solid_angle_winding(points, triangles, grid.index_to_world(differ[:, ::-1]))
        assert np.allclose(exact, 2.0, atol=1e-6)
    assert parity.sum() > 1000


def test_winding_and_parity_agree_on_nested_shells_made_in_code():
    shells = joined(sphere(20.0, around=128, across=64), flipped(sphere(12.0, around=96, across=48)),
                    sphere(6.0, around=64, across=32), torus(30.0, 4.0, around=128, across=32))
    grid = _grid_around(shells[0], 80)
    assert np.array_equal(voxelise(*shells, grid), voxelise(*shells, grid, inside="winding"))


def test_self_intersecting_pieces_are_united_by_winding_and_cancelled_by_parity():
    a = box((0.5, 0.5, 0.5), (10.5, 10.5, 10.5))
    b = box((5.5, 5.5, 5.5), (15.5, 15.5, 15.5))
    grid = Grid((17, 17, 17))
    union = voxelise(*joined(a, b), grid, inside="winding")
    parity = voxelise(*joined(a, b), grid)
    assert union.sum() == 2 * 1000 - 125
    assert parity.sum() == 2 * 1000 - 2 * 125


@pytest.mark.parametrize("cut", ["flat", "wavy"])
def test_open_sphere_matches_the_thresholded_exact_winding_number(cut):
    """A sphere with a hole (flat: the cap beyond x = 8 mm removed, facing the rows; wavy: the top above a wavy line
    around z, so the fan over the hole
    is far from planar and its winding number exceeds 1/2 near it): every voxel agrees with the exact winding
    number thresholded at 1/2, except where that number is within the far-field allowance of 1/2."""
    points, triangles = sphere(10.0, around=96, across=48)
    centres = points[triangles].mean(axis=1)
    angle = np.arctan2(centres[:, 1], centres[:, 0])
    if cut == "flat":
        keep = centres[:, 0] < 8.0
    else:
        keep = centres[:, 2] < 6.0 + 3.0 * np.sin(3 * angle)
    triangles = triangles[keep]
    grid = _grid_around(points, 40, padding=3)
    mask, report = voxelise_with_report(points, triangles, grid, inside="winding")
    assert report.caps == 1 and report.boundary_edges >= 48
    exact = solid_angle_winding(points, triangles, _centres(grid)).reshape(grid.shape)
    clear = np.abs(exact - 0.5) > 0.02
    assert np.array_equal(mask[clear], (exact[clear] >= 0.5).astype(np.uint8))
    assert np.count_nonzero(~clear) < 0.01 * mask.size
    # parity on the same open mesh is no solid: rows through the hole run on to the grid's end, or stop short
    assert np.count_nonzero(voxelise(points, triangles, grid) != mask) > 100


def test_bunny_with_holes_by_winding_is_within_one_percent_of_the_hole_filled_bunny_by_parity():
    from algorithms.common.vtk_bridge import polydata_arrays, run_algorithm
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData, vtkTriangleFilter
    from vtkmodules.vtkFiltersModeling import vtkFillHolesFilter

    points, triangles, polydata = real_mesh("stanford-bunny.obj.gz")
    fill = vtkFillHolesFilter()
    fill.SetInputData(polydata)
    fill.SetHoleSize(1e6)
    triangulate = vtkTriangleFilter()
    triangulate.SetInputConnection(fill.GetOutputPort())
    clean = vtkCleanPolyData()
    clean.SetInputConnection(triangulate.GetOutputPort())
    filled_points, filled_triangles = polydata_arrays(run_algorithm(clean))
    # VTK leaves 18 edges of the largest (non-planar) hole open, and 215 edges where its patches meet the bunny
    # with the opposite orientation; fans over that chain (18 + 2 x 215 edges) close the filled bunny (for parity,
    # the doubled fans over the orientation seams cancel)
    from algorithms.compare.topology import edge_manifoldness

    edges = edge_manifoldness(filled_points, filled_triangles)
    assert (edges.odd_edges, edges.inconsistent_edges) == (18, 215)
    rest = boundary_caps(filled_points, filled_triangles)
    assert rest.edges == 18 + 2 * 215
    filled_points, filled_triangles = rest.points, np.concatenate([filled_triangles, rest.triangles])
    grid = _grid_around(points, 128)
    winding, report = voxelise_with_report(points, triangles, grid, inside="winding")
    filled = voxelise(filled_points, filled_triangles, grid)
    assert report.caps == 5 and report.boundary_edges == 223
    assert abs(int(winding.sum()) - int(filled.sum())) < 0.01 * filled.sum()
    # parity on the bunny with holes is not a solid: rows through the holes run on to the end of the grid
    # (measured: 216 voxels differ from the filled bunny by winding, 8,704 by parity at this size)
    parity = voxelise(points, triangles, grid)
    assert np.count_nonzero(parity != filled) > 10 * np.count_nonzero(winding != filled)
