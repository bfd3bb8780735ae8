"""Framing the object tightly: the box of what the views actually show (the voxels at or above the visible threshold,
not the whole scanned box) and a camera from a standard side that fits that box's projection into the view.

The fit is exact for the box: every corner is projected onto the camera's screen axes; for a perspective camera
the distance is the smallest at which every corner lies within the vertical and horizontal fields of view (a
corner nearer the camera needs more room), for a parallel camera the scale is the larger half-extent. A small
margin (4 % by default) keeps the silhouette off the border.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from algorithms.common.camera import Camera

from .pipeline.cameras import DEFAULT_VIEW_ANGLE, STANDARD_VIEWS

MAX_SCANNED_VOXELS = 4_000_000


def visible_threshold(iso: float | None, transfer_function=None) -> float | None:
    """The lowest value the views draw: the isovalue, or lower where the transfer function is already visible."""
    values = [] if iso is None else [float(iso)]
    if transfer_function is not None:
        points = transfer_function.opacity_points
        for index, (value, opacity) in enumerate(points):
            if opacity > 0:
                values.append(points[index - 1][0] if index > 0 else value)
                break
    return min(values) if values else None


def content_bounds(volume, threshold: float | None) -> tuple[float, ...] | None:
    """LPS bounds ``(xmin, xmax, ymin, ymax, zmin, zmax)`` of the voxels at or above ``threshold`` (the whole volume
    without one); None when no voxel reaches it. Large volumes are scanned on a regular subsample, widened by
    the stride so nothing is cut."""
    if threshold is None:
        return tuple(volume.world_bounds)
    array = volume.array
    stride = max(1, int(math.ceil((array.size / MAX_SCANNED_VOXELS) ** (1 / 3))))
    above = array[::stride, ::stride, ::stride] >= threshold
    if not above.any():
        return None
    ranges = []
    for axis in (2, 1, 0):  # i, j, k
        others = tuple(a for a in range(3) if a != axis)
        hits = np.flatnonzero(above.any(axis=others))
        n = array.shape[axis]
        ranges.append((max(hits[0] * stride - (stride - 1), 0), min(hits[-1] * stride + (stride - 1), n - 1)))
    corners = np.array([[i, j, k] for i in ranges[0] for j in ranges[1] for k in ranges[2]], dtype=np.float64)
    corners = np.concatenate([corners - 0.5, corners + 0.5])  # the voxels' own extent
    world = volume.index_to_world(corners)
    low, high = world.min(axis=0), world.max(axis=0)
    return (low[0], high[0], low[1], high[1], low[2], high[2])


def tight_camera(bounds: Sequence[float], *, view: str = "anterior", aspect: float = 1.0, parallel: bool = False,
                 view_angle: float = DEFAULT_VIEW_ANGLE, margin: float = 0.04) -> Camera:
    """A camera from a standard side fitting the box ``bounds`` (LPS mm) into an image of ``aspect`` (w / h)."""
    if view not in STANDARD_VIEWS:
        raise ValueError(f"unknown view {view!r}; choose one of {', '.join(STANDARD_VIEWS)}")
    low, high = np.asarray(bounds[0::2], dtype=np.float64), np.asarray(bounds[1::2], dtype=np.float64)
    if not (np.all(np.isfinite(low)) and np.all(high >= low)) or np.all(high - low <= 0):
        raise ValueError(f"the object to frame must have a positive size, got bounds {list(bounds)}")
    direction, up = (np.asarray(v, dtype=np.float64) for v in STANDARD_VIEWS[view])
    right = np.cross(direction, up)
    centre = (low + high) / 2
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    offsets = corners - centre
    x, y, depth = offsets @ right, offsets @ up, offsets @ direction
    aspect = max(float(aspect), 1e-3)
    scale = 1.0 + margin
    half_v = math.radians(view_angle) / 2
    half_h = math.atan(math.tan(half_v) * aspect)
    distance = float(np.max(np.maximum(np.abs(x) * scale / math.tan(half_h), np.abs(y) * scale / math.tan(half_v))
                            - depth))
    distance = max(distance, float(np.max(-depth)) + 1e-3)
    parallel_scale = float(max(np.max(np.abs(y)), np.max(np.abs(x)) / aspect) * scale)
    return Camera(position=tuple(centre - direction * distance), focal_point=tuple(centre), view_up=tuple(up),
                  view_angle=view_angle, parallel_projection=parallel, parallel_scale=max(parallel_scale, 1e-3))


def framing_camera(item, *, iso=None, transfer_function=None, **kwargs) -> Camera:
    """The tight camera for a scene item: a gridded item is framed by what is visible at ``iso`` (or where the
    transfer function becomes opaque), a mesh by its bounds."""
    volume = getattr(item, "volume", None)
    bounds = None
    if volume is not None:
        threshold = 0.5 if "label_table" in volume.metadata else visible_threshold(iso, transfer_function)
        bounds = content_bounds(volume, threshold)
        if bounds is None:
            bounds = content_bounds(volume, None)
    else:
        bounds = item.bounds
    return tight_camera(bounds, **kwargs)
