"""Cameras in patient coordinates (LPS mm): the standard views, the default camera, turning sequences, and the one
conversion of a world camera into an item's own frame.

Volumes and surfaces extracted from them are built in the *volume frame* (index times spacing, mm) and placed in the
patient by their prop's user matrix (``Volume.local_to_world``); cameras are always in world (LPS) coordinates.
Our software renderers work in the volume frame, so the pipeline converts a world camera with
:func:`camera_in_frame` - nowhere else.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from algorithms.common.camera import Camera

from ..volume import Volume

DEFAULT_VIEW_ANGLE = 30.0

#: Camera presets in LPS: name -> (direction of projection, view up). "anterior" looks at the patient's face.
STANDARD_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "anterior": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "posterior": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "left": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "right": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "superior": ((0.0, 0.0, -1.0), (0.0, -1.0, 0.0)),
    "inferior": ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),
}


def fit_camera(
    centre: Sequence[float],
    radius: float,
    *,
    view: str = "anterior",
    azimuth: float = 0.0,
    elevation: float = 0.0,
    parallel: bool = False,
    aspect: float = 1.0,
    view_angle: float = DEFAULT_VIEW_ANGLE,
) -> Camera:
    """A camera looking at ``centre`` from a standard side with a sphere of ``radius`` mm just in view.

    ``azimuth`` and ``elevation`` (degrees) then orbit it like ``vtkCamera.Azimuth``/``Elevation``; ``aspect`` is
    the image's width / height and the fit accounts for it.
    """
    if view not in STANDARD_VIEWS:
        raise ValueError(f"unknown view {view!r}; choose one of {', '.join(STANDARD_VIEWS)}")
    if not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"the object to frame must have a positive size, got a radius of {radius} mm")
    direction, view_up = (np.asarray(v) for v in STANDARD_VIEWS[view])
    centre = np.asarray(centre, dtype=np.float64)
    half_angle = math.radians(view_angle) / 2
    if aspect < 1.0:  # the horizontal field of view is the narrower one
        half_angle = math.atan(math.tan(half_angle) * aspect)
    distance = radius / math.sin(half_angle)
    camera = Camera(
        position=tuple(centre - direction * distance),
        focal_point=tuple(centre),
        view_up=tuple(view_up),
        view_angle=view_angle,
        parallel_projection=parallel,
        parallel_scale=radius / min(1.0, aspect),
    )
    return camera.orbited(azimuth, elevation) if (azimuth or elevation) else camera


def bounding_sphere(bounds: Sequence[float]) -> tuple[np.ndarray, float]:
    """Centre and radius (mm) of the sphere around axis-aligned ``(xmin, xmax, ymin, ymax, zmin, zmax)``."""
    low = np.asarray(bounds[0::2], dtype=np.float64)
    high = np.asarray(bounds[1::2], dtype=np.float64)
    return (low + high) / 2, 0.5 * float(np.linalg.norm(high - low))


def default_camera(item, **kwargs) -> Camera:
    """The default camera for a scene item (or a :class:`~app.volume.Volume`): anterior, the whole item in view.

    A volume is framed by its box including the voxels' own extent (so a one-voxel rim is not clipped).
    """
    volume = item if isinstance(item, Volume) else getattr(item, "volume", None)
    if volume is not None:
        radius = 0.5 * float(np.linalg.norm(np.asarray(volume.dimensions) * np.asarray(volume.spacing)))
        return fit_camera(volume.centre, radius, **kwargs)
    centre, radius = bounding_sphere(item.bounds)
    return fit_camera(centre, radius, **kwargs)


def turning_cameras(camera: Camera, frames: int, step_degrees: float = 2.0) -> list[Camera]:
    """``frames`` cameras turning by ``step_degrees`` azimuth each, starting one step after ``camera``."""
    if frames < 1:
        raise ValueError(f"frames must be at least 1, got {frames}")
    return [camera.orbited(azimuth=step_degrees * (i + 1)) for i in range(frames)]


def camera_in_frame(camera: Camera, local_to_world: np.ndarray) -> Camera:
    """A world (LPS) camera expressed in the frame that ``local_to_world`` (4x4, rigid) places in the world."""
    return camera.transformed(np.linalg.inv(np.asarray(local_to_world, dtype=np.float64)))
