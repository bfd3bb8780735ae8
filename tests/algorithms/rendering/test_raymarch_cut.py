"""Cut-away tools in the ray marcher (issue 15, source 002 section 2.5): the leap over samples that exact-distance
tools surely remove changes no pixel, and takes fewer samples."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.fields.selection import box_tool, sphere_tool, tool_set
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


@pytest.mark.parametrize("evaluation", ["binary", "distance"])
@pytest.mark.parametrize("lighting", ["emission", "phong"])
def test_leaping_through_removed_samples_leaves_the_image_unchanged(scene, evaluation, lighting):
    volume, camera, table = scene
    frame = volume.local_to_world
    tools = [sphere_tool((20.0, -60.0, 20.0), 60.0), box_tool((-40.0, -40.0, 40.0), (60, 50, 70), (0, 20, 45))]
    exact = tool_set(tools, frame, evaluation=evaluation, width=min(volume.spacing))
    assert exact.packed()[7][4] == 1.0
    # The same tools with a transform scaled by 1 + 1e-6: no longer "exact", so every sample is tested.
    scaled = exact.with_settings(matrices=exact.matrices @ np.diag([1 + 1e-6, 1.0, 1.0, 1.0]))
    assert scaled.packed()[7][4] == 0.0
    renderer = RaymarchRenderer(volume.array, volume.spacing, table, lighting=lighting)
    leaped = renderer.render(camera, 96, 96, tools=exact)
    tested = renderer.render(camera, 96, 96, tools=scaled)
    plain = renderer.render(camera, 96, 96)
    assert np.abs(leaped.rgba - tested.rgba).max() < 1e-4
    assert np.abs(leaped.rgba - plain.rgba).max() > 0.2  # the tools do cut
    assert leaped.stats["samples_per_ray"] < tested.stats["samples_per_ray"]
