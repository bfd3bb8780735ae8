"""Cut-away tools in the ray marcher (issue 15, source 002 section 2.5): the leap over samples that the tools surely
remove (shapes by their distance, grid tools by their depth tables) changes no pixel and takes fewer samples; a
binary-mask grid tool shades its grid box with the data gradient away from the cut."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.fields.cutaway_tools import box_tool, sphere_tool, tool_set
from algorithms.rendering.raymarch import RaymarchRenderer


@pytest.fixture(scope="module")
def scene():
    from app.datasets import ct_head_phantom
    from app.pipeline.cameras import default_camera
    from app.transfer import transfer_function_for

    volume = ct_head_phantom(shape=(54, 128, 128), spacing=(1.875, 1.875, 4.0))
    camera = default_camera(volume, azimuth=30, elevation=15).transformed(np.linalg.inv(volume.local_to_world))
    table = transfer_function_for(volume, "ct-bone").to_table(volume.value_range)
    return volume, camera, table


def _renderer(volume, table, lighting):
    return RaymarchRenderer(volume.array, volume.spacing, table, lighting=lighting)


@pytest.mark.parametrize("evaluation", ["binary", "distance"])
@pytest.mark.parametrize("lighting", ["emission", "phong"])
def test_leaping_through_removed_samples_leaves_the_image_unchanged(scene, evaluation, lighting):
    volume, camera, table = scene
    frame = volume.local_to_world
    # The sphere takes the front of the skull away (the camera sees the frontal bone), the box a corner behind it.
    tools = [sphere_tool((20.0, -90.0, 20.0), 60.0), box_tool((-40.0, -40.0, 40.0), (60, 50, 70), (0, 20, 45))]
    placed = tool_set(tools, frame, evaluation=evaluation, width=min(volume.spacing))
    # Also a non-rigid placement (the sphere stretched into an ellipsoid): the leap is divided by the largest
    # singular value of the matrix, so it stays conservative.
    stretched = placed.with_settings(matrices=placed.matrices @ np.diag([1.3, 0.8, 1.0, 1.0]))
    renderer = _renderer(volume, table, lighting)
    plain = renderer.render(camera, 96, 96)
    for tools_set in (placed, stretched):
        assert tools_set.packed()[7][4] == 1.0 and np.all(tools_set.packed()[3][:, 3] > 0)
        leaped = renderer.render(camera, 96, 96, tools=tools_set)
        tested = renderer.render(camera, 96, 96, tools=tools_set.with_settings(leap=False))
        assert np.abs(leaped.rgba - tested.rgba).max() < 1e-4
        assert np.abs(leaped.rgba - plain.rgba).max() > 0.2  # the tools do cut
        assert leaped.stats["samples_per_ray"] < tested.stats["samples_per_ray"]


def _ball_mask_tool(mode, *, role="mask"):
    """A ball of radius 35 mm with a wedge cut out of it, on a 40-voxel grid, placed by a rotated, anisotropically
    scaled transform (so the leap's singular-value scaling matters)."""
    from algorithms.common.grid import Grid
    from algorithms.fields.cutaway_tools import grid_tool, rotation_matrix

    grid = Grid.around([-40, 40, -40, 40, -40, 40], voxels=40, padding=2)
    k, j, i = np.indices(grid.shape)
    world = grid.index_to_world(np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)).reshape(grid.shape + (3,))
    radius = np.linalg.norm(world, axis=-1)
    inside = (radius < 35.0) & ~((world[..., 0] > 10.0) & (world[..., 1] > 10.0))
    values = inside if role == "mask" else np.where(inside, -1.0, 1.0) * np.abs(radius - 35.0)
    transform = np.eye(4)
    transform[:3, :3] = rotation_matrix((10, 20, 30)) @ np.diag([1.3, 1.0, 0.8])
    transform[:3, 3] = (20.0, -95.0, 20.0)  # through the frontal bone, which the camera sees
    return grid_tool(values, grid, role=role, transform=transform, mode=mode)


@pytest.mark.parametrize("mode", ["remove", "keep"])
@pytest.mark.parametrize("evaluation", ["binary", "distance"])
@pytest.mark.parametrize("lighting", ["emission", "phong"])
def test_grid_tools_leap_without_changing_the_image(scene, mode, evaluation, lighting):
    volume, camera, table = scene
    tool = _ball_mask_tool(mode)
    tools = tool_set([tool], volume.local_to_world, evaluation=evaluation, width=min(volume.spacing))
    assert tools.grid_leaps_valid() and tools.packed()[3][0, 3] > 0
    renderer = _renderer(volume, table, lighting)
    leaped = renderer.render(camera, 96, 96, tools=tools)
    tested = renderer.render(camera, 96, 96, tools=tools.with_settings(leap=False))
    plain = renderer.render(camera, 96, 96)
    assert np.abs(leaped.rgba - tested.rgba).max() < 1e-4
    assert np.abs(leaped.rgba - plain.rgba).max() > 0.2
    assert leaped.stats["samples_per_ray"] < tested.stats["samples_per_ray"]


def test_grid_leap_depths_are_not_used_for_another_distance_width(scene):
    volume, _, _ = scene
    tools = tool_set([_ball_mask_tool("remove")], volume.local_to_world, evaluation="distance", width=1.0)
    assert tools.grid_leaps_valid()
    assert not tools.with_settings(width=3.0).grid_leaps_valid()
    assert tools.with_settings(width=3.0).packed()[3][0, 3] == 0.0  # that grid tool no longer leaps
    assert tools.with_settings(evaluation="binary").grid_leaps_valid()  # r <= -w/2 implies r < 0


def test_a_mask_tool_shades_its_grid_box_with_the_data_gradient_away_from_the_cut(scene):
    """A binary-mask tool's field is +-h/2 everywhere off the cut; a kept sample in its grid box is not "on the cut"
    (before the band was kept below h/2, such samples took a vanishing tool gradient: ambient light only)."""
    from algorithms.common.grid import Grid
    from algorithms.fields.cutaway_tools import grid_tool

    volume, camera, table = scene
    bounds = np.asarray(volume.grid.world_bounds)
    grid = Grid.around(bounds, voxels=64, padding=2)  # h/2 below the default band (1.5 x 1.875 mm)
    mask = np.zeros(grid.shape, dtype=bool)
    mask[:2, :2, :2] = True  # removes a corner outside the data only; the grid box covers the whole volume
    tools = tool_set([grid_tool(mask, grid)], volume.local_to_world, width=min(volume.spacing))
    assert tools.band < 0.5 * float(np.mean(grid.spacing))
    renderer = _renderer(volume, table, "phong")
    cut = renderer.render(camera, 96, 96, tools=tools)
    plain = renderer.render(camera, 96, 96)
    assert np.abs(cut.rgba - plain.rgba).max() < 1e-4


def _every_kind_of_tool(mode):
    from algorithms.fields.cutaway_tools import cylinder_tool, plane_tool

    return [sphere_tool((20.0, -60.0, 20.0), 45.0, mode=mode),
            box_tool((-40.0, -40.0, 40.0), (60, 50, 70), (0, 20, 45), mode=mode),
            cylinder_tool((10.0, -70.0, 10.0), 35.0, 100.0, (30, 0, 60), mode=mode),
            plane_tool((0.0, 0.0, 60.0), (0.2, 0.3, 1.0), mode=mode),
            _ball_mask_tool(mode)]


@pytest.mark.parametrize("mode", ["remove", "keep"])
@pytest.mark.parametrize("evaluation", ["binary", "distance"])
@pytest.mark.parametrize("lighting", ["emission", "phong"])
def test_testing_only_where_a_ray_meets_the_tools_leaves_the_image_unchanged(scene, mode, evaluation, lighting):
    # Per ray, the tools are evaluated only where the ray passes within the test margin of a tool, keep tools clip
    # the ray to their bounds, and a chord through a remove shape is jumped; every sample is kept or removed exactly
    # as the plain per-sample test (no bounds, no leap) decides.
    volume, camera, table = scene
    renderer = _renderer(volume, table, lighting)
    plain = renderer.render(camera, 96, 96)
    for tool in _every_kind_of_tool(mode):
        placed = tool_set([tool], volume.local_to_world, evaluation=evaluation, width=min(volume.spacing))
        stretched = placed.with_settings(matrices=placed.matrices @ np.diag([1.3, 0.8, 1.0, 1.0]))
        for tools in (placed, stretched):
            bounded = renderer.render(camera, 96, 96, tools=tools)
            everywhere = renderer.render(camera, 96, 96, tools=tools.with_settings(bounds=False, leap=False))
            assert np.abs(bounded.rgba - everywhere.rgba).max() < 1e-4, tool.shape
            assert np.abs(bounded.rgba - plain.rgba).max() > 0.05, tool.shape  # the tool does cut
    both = tool_set(_every_kind_of_tool(mode)[:2], volume.local_to_world, evaluation=evaluation,
                    width=min(volume.spacing))
    assert np.abs(renderer.render(camera, 96, 96, tools=both).rgba
                  - renderer.render(camera, 96, 96, tools=both.with_settings(bounds=False, leap=False)).rgba).max() < 1e-4
