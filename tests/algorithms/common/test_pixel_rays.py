"""The per-pixel ray of the numba kernels: it passes through the pixel's centre, for both projections."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.camera import Camera
from algorithms.common.pixel_rays import pixel_ray

WIDTH, HEIGHT = 7, 5


def rays(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions ``(HEIGHT, WIDTH, 3)`` from :func:`pixel_ray`, row 0 at the top."""
    frame = np.ascontiguousarray(camera.ray_frame(WIDTH, HEIGHT))
    origins = np.empty((HEIGHT, WIDTH, 3))
    directions = np.empty((HEIGHT, WIDTH, 3))
    for row in range(HEIGHT):
        for col in range(WIDTH):
            ox, oy, oz, dx, dy, dz = pixel_ray(frame, bool(camera.parallel_projection), col, row)
            origins[row, col] = ox, oy, oz
            directions[row, col] = dx, dy, dz
    return origins, directions


@pytest.mark.parametrize("parallel", [False, True])
def test_rays_hit_the_pixel_centres(parallel):
    camera = Camera(position=(10.0, -40.0, 25.0), focal_point=(2.0, 3.0, -1.0), view_up=(0.2, 0.3, 1.0),
                    view_angle=40.0, parallel_projection=parallel, parallel_scale=12.0)
    origins, directions = rays(camera)
    centres = np.stack(np.meshgrid(np.arange(WIDTH) + 0.5, np.arange(HEIGHT) + 0.5), axis=-1)  # (col, row)
    forward = camera.direction
    for t in (1.0, 35.0, 90.0):
        points = origins + t * directions
        projected = camera.project(points.reshape(-1, 3), WIDTH, HEIGHT).reshape(HEIGHT, WIDTH, 2)
        np.testing.assert_allclose(projected, centres, atol=1e-9)
        # Perspective directions are scaled so that o + t d lies t mm in front of the camera plane.
        depth = (points - np.asarray(camera.position)) @ forward
        np.testing.assert_allclose(depth - (origins - np.asarray(camera.position)) @ forward, t, rtol=1e-12)
    if parallel:
        np.testing.assert_allclose(directions, np.broadcast_to(forward, directions.shape), atol=1e-15)
        np.testing.assert_allclose((origins - np.asarray(camera.position)) @ forward, 0.0, atol=1e-12)
    else:
        np.testing.assert_allclose(origins, np.broadcast_to(camera.position, origins.shape), atol=0)


@pytest.mark.parametrize("parallel", [False, True])
def test_rays_are_the_cameras_own_pixel_rays(parallel):
    camera = Camera(position=(0.0, 0.0, 50.0), focal_point=(1.0, 2.0, 0.0), view_up=(0.0, 1.0, 0.0),
                    parallel_projection=parallel, parallel_scale=8.0)
    origins, directions = rays(camera)
    expected_origins, expected_directions = camera.pixel_rays(WIDTH, HEIGHT)
    unit = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    np.testing.assert_allclose(origins, expected_origins, atol=1e-12)
    np.testing.assert_allclose(unit, expected_directions, atol=1e-12)
    # The top-left pixel's ray is up and to the left of the view direction; the bottom-right one the opposite.
    right, up, _ = camera.basis()
    offsets = origins if parallel else unit
    assert offsets[0, 0] @ right < offsets[-1, -1] @ right and offsets[0, 0] @ up > offsets[-1, -1] @ up
