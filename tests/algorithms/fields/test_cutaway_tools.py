"""Cut-away tools (issue 15; source 002, 2.5 and 3.3.1): binary masks against VTK's vtkImageStencil fed by
vtkImplicitFunctionToImageStencil, an analytic 45-degree box, combination, keep mode, grid tools and the CSG
difference used for surfaces."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.cutaway import removal_field, removal_normals, removal_values
from algorithms.common.grid import Grid
from algorithms.fields.cutaway_tools import (
    box_tool,
    cut_volume,
    cylinder_tool,
    grid_tool,
    plane_tool,
    removed_mask,
    rotation_matrix,
    sphere_tool,
    tool_set,
)
from algorithms.references.vtk_cutaway import implicit_function, stencil_mask

SHAPE = (41, 53, 67)  # (nz, ny, nx)
SPACING = (0.83, 1.07, 1.61)  # (sx, sy, sz) mm: anisotropic on purpose
ORIGIN = np.array([-20.0, 13.0, 4.0])  # the volume's LPS origin: the tools are in LPS, the grid frame is not


def _frame():
    """Volume frame (index times spacing) -> LPS mm: a translation by the origin."""
    frame = np.eye(4)
    frame[:3, 3] = ORIGIN
    return frame


def _centres_lps():
    nz, ny, nx = SHAPE
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    return np.stack([i * SPACING[0], j * SPACING[1], k * SPACING[2]], axis=-1) + ORIGIN


def _vtk_mask(tool):
    frame_to_tool = np.linalg.inv(tool.matrix) @ _frame()
    return stencil_mask(SHAPE, SPACING, [implicit_function(tool.shape, tool.size, frame_to_tool)])


@pytest.mark.parametrize("tool", [
    sphere_tool((12.3, 40.1, 37.7), 17.3),
    box_tool((15.2, 38.9, 33.1), (31.3, 17.9, 24.7), (0.0, 0.0, 45.0)),
    box_tool((14.1, 41.3, 31.9), (29.3, 19.7, 21.1), (30.0, 45.0, 10.0)),
    cylinder_tool((11.7, 37.2, 35.3), 9.3, 27.1, (45.0, 0.0, 0.0)),
    plane_tool((10.3, 40.7, 30.9), (1.0, -2.0, 0.5)),
], ids=["sphere", "box-45z", "box-oblique", "cylinder", "plane"])
def test_binary_mask_matches_vtk_image_stencil(tool):
    ours = removed_mask(tool_set([tool], _frame()), SHAPE, SPACING)
    reference = _vtk_mask(tool)
    assert 0.01 < ours.mean() < 0.9, "the tool should remove part of the grid, not all or nothing"
    assert np.array_equal(ours, reference), f"{int((ours != reference).sum())} voxels differ from vtkImageStencil"


def test_box_rotated_45_degrees_removes_the_right_voxels():
    centre, sizes = np.array([14.2, 40.3, 32.6]), np.array([30.3, 12.1, 20.7])
    tool = box_tool(centre, sizes, (0.0, 0.0, 45.0))
    ours = removed_mask(tool_set([tool], _frame()), SHAPE, SPACING)
    # Analytic: the box's own axes are x and y turned by 45 degrees about z.
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    d = _centres_lps() - centre
    u = c * d[..., 0] + s * d[..., 1]
    v = -s * d[..., 0] + c * d[..., 1]
    inside = (np.abs(u) < sizes[0] / 2) & (np.abs(v) < sizes[1] / 2) & (np.abs(d[..., 2]) < sizes[2] / 2)
    assert inside.sum() > 1000
    assert np.array_equal(ours, inside)
    # An axis-aligned box of the same sizes removes a clearly different set (the rotation is applied).
    straight = removed_mask(tool_set([box_tool(centre, sizes)], _frame()), SHAPE, SPACING)
    assert (straight != ours).sum() > 0.2 * inside.sum()


def test_rotation_order_is_x_then_y_then_z():
    r = rotation_matrix((90.0, 0.0, 90.0))
    # x first sends y to z; then z about z leaves z. So y -> z; and x -> (about z) y.
    assert np.allclose(r @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    assert np.allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-12)


def test_several_tools_remove_the_union_and_keep_keeps_the_inside():
    a = sphere_tool((10.0, 30.0, 30.0), 9.0)
    b = box_tool((30.0, 50.0, 40.0), (12.0, 14.0, 16.0), (0, 30, 0))
    union = removed_mask(tool_set([a, b], _frame()), SHAPE, SPACING)
    only_a = removed_mask(tool_set([a], _frame()), SHAPE, SPACING)
    only_b = removed_mask(tool_set([b], _frame()), SHAPE, SPACING)
    assert only_a.any() and only_b.any()
    assert np.array_equal(union, only_a | only_b)
    keep = removed_mask(tool_set([box_tool((20.0, 40.0, 30.0), (20.0, 20.0, 20.0), mode="keep")], _frame()), SHAPE,
                        SPACING)
    straight = removed_mask(tool_set([box_tool((20.0, 40.0, 30.0), (20.0, 20.0, 20.0))], _frame()), SHAPE, SPACING)
    assert np.array_equal(keep, ~straight)


def test_hidden_tools_are_ignored():
    tool = sphere_tool((10.0, 30.0, 30.0), 9.0).moved(visible=False)
    assert len(tool_set([tool], _frame())) == 0
    assert not removed_mask(tool_set([tool], _frame()), SHAPE, SPACING).any()


def test_grid_tool_of_a_mask_with_a_transform_matches_the_shape_it_was_made_from():
    # A voxelised sphere on its own, coarser grid, moved by a transform: it removes (up to the mask's own voxels)
    # what the analytic sphere at the moved place removes.
    grid = Grid.around((-10, 10, -10, 10, -10, 10), spacing=(0.5, 0.5, 0.5), padding=2)
    nx, ny, nz = grid.dimensions
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    points = grid.index_to_world(np.stack([i, j, k], axis=-1).reshape(-1, 3)).reshape(nz, ny, nx, 3)
    mask = np.linalg.norm(points, axis=-1) < 8.0
    transform = np.eye(4)
    transform[:3, :3] = rotation_matrix((0, 0, 30))
    transform[:3, 3] = (15.0, 40.0, 30.0)
    from_grid = removed_mask(tool_set([grid_tool(mask, grid, transform=transform)], _frame()), SHAPE, SPACING)
    analytic = removed_mask(tool_set([sphere_tool((15.0, 40.0, 30.0), 8.0)], _frame()), SHAPE, SPACING)
    assert analytic.sum() > 300
    assert (from_grid != analytic).sum() <= 0.1 * analytic.sum()


def _leap_case(mode, evaluation):
    """A wedge-cut ball mask on a coarse grid, rotated and scaled anisotropically, with points around it."""
    grid = Grid.around((-10, 10, -10, 10, -10, 10), spacing=(0.7, 0.7, 0.7), padding=2)
    nx, ny, nz = grid.dimensions
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    points = grid.index_to_world(np.stack([i, j, k], axis=-1).reshape(-1, 3)).reshape(nz, ny, nx, 3)
    mask = (np.linalg.norm(points, axis=-1) < 8.0) & ~((points[..., 0] > 2.0) & (points[..., 2] > 1.0))
    transform = np.eye(4)
    transform[:3, :3] = rotation_matrix((20, 35, 50)) @ np.diag([1.4, 0.9, 1.1])
    transform[:3, 3] = (15.0, 40.0, 30.0)
    tool = grid_tool(mask, grid, transform=transform, mode=mode)
    return tool_set([tool], _frame(), evaluation=evaluation, width=0.5)  # below h = 0.7 mm: a mask can remove fully


@pytest.mark.parametrize("mode", ["remove", "keep"])
@pytest.mark.parametrize("evaluation", ["binary", "distance"])
def test_grid_tool_leaps_stay_inside_the_removed_region(mode, evaluation):
    # The leap of a grid tool (its depth table made once, scaled by the matrix's largest singular value) must be
    # conservative: every point closer than the leap is still fully removed (g < 0, or g <= -width/2).
    from algorithms.common.cutaway import leap_at

    tools = _leap_case(mode, evaluation)
    packed = tools.packed()
    rng = np.random.default_rng(11)
    centre = np.array([15.0, 40.0, 30.0]) - ORIGIN  # the tool's centre in the volume frame (mm)
    starts = centre + rng.uniform(-14.0, 14.0, size=(4000, 3))
    limit = 0.0 if evaluation == "binary" else -0.5 * tools.width
    leaps = np.array([leap_at(packed, *p) for p in starts])
    assert (leaps > 1.0).sum() > 50 and leaps.max() > 2.0, "the tool should allow leaps of more than 1 mm"
    removed = removal_values(tools, starts)
    assert np.all(removed[leaps > 0] <= limit if evaluation == "distance" else removed[leaps > 0] < limit)
    chosen = np.flatnonzero(leaps > 0)
    directions = rng.normal(size=(len(chosen), 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    for fraction in (0.25, 0.5, 0.75, 0.999):
        ends = starts[chosen] + directions * (fraction * leaps[chosen])[:, None]
        g = removal_values(tools, ends)
        assert np.all(g <= limit if evaluation == "distance" else g < limit), (
            f"{int((g > limit).sum())} points within the leap are not removed")


def test_grid_tool_depth_tables_are_made_once_and_follow_the_tool():
    tools = _leap_case("remove", "binary")
    grid = Grid.around((-5, 5, -5, 5, -5, 5), spacing=(1.0, 1.0, 1.0), padding=1)
    tool = grid_tool(np.ones(grid.shape, bool), grid)
    assert tool.leap_depths().max() > 1.0  # a full mask: deep inside, the ray may leap
    moved = tool.moved(centre=(3.0, 4.0, 5.0))
    assert moved.leap_depths() is tool.leap_depths()  # the table is not made again when the tool moves
    assert tool.moved(mode="keep").leap_depths() is not tool.leap_depths()  # another mode: another table
    assert tools.grid_leaps.shape == tools.grid_values.shape


def test_distance_normals_follow_the_sphere():
    tools = tool_set([sphere_tool((0.0, 0.0, 0.0), 10.0)], evaluation="distance")
    rng = np.random.default_rng(3)
    directions = rng.normal(size=(200, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points = directions * 10.2
    assert np.allclose(removal_values(tools, points), 0.2, atol=1e-9)  # kept, 0.2 mm from the cut
    assert np.allclose(removal_values(tools, directions * 9.5), -0.5, atol=1e-9)  # removed
    normals = removal_normals(tools, points)
    # grad g points out of the removed region: away from the centre of a removed sphere.
    assert np.all(np.einsum("ij,ij->i", normals, directions) > np.cos(np.radians(1.0)))


def test_cut_volume_caps_with_the_tool_and_leaves_the_rest():
    values = np.full(SHAPE, 1000.0, dtype=np.float32)
    tools = tool_set([sphere_tool((20.0, 40.0, 30.0), 10.0)], _frame(), evaluation="distance")
    cut = cut_volume(values, tools, SPACING, 300.0)
    g = removal_field(tools, SHAPE, SPACING)
    assert np.all(cut[g < 0] < 300.0)
    # Values are only lowered towards iso next to the cut (at most eight voxel diagonals), never below it there.
    assert np.all(cut[g > 8 * np.linalg.norm(SPACING)] == 1000.0)
    assert np.all(cut[g > 0] > 300.0)
    binary = cut_volume(values, tools.with_settings(evaluation="binary"), SPACING, 300.0)
    assert np.all(binary[g < 0] < 300.0) and np.all(binary[g >= 0] == 1000.0)


def test_bad_tools_are_refused_plainly():
    with pytest.raises(ValueError, match="positive radius"):
        sphere_tool((0, 0, 0), -1.0)
    with pytest.raises(ValueError, match="three positive full sizes"):
        box_tool((0, 0, 0), (1.0, 2.0))
    with pytest.raises(ValueError, match="non-zero normal"):
        plane_tool((0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="remove or keep"):
        sphere_tool((0, 0, 0), 1.0, mode="cut")
