"""A plain camera shared by our software renderers, with VTK's conventions.

The renderers (ray marching, texture slicing, shear-warp) take a :class:`Camera` expressed in the *volume frame*:
the frame in which voxel ``(i, j, k)`` sits at ``(i * sx, j * sy, k * sz)`` millimetres (origin at the first
voxel, axes along the array axes). The application converts the world (LPS) camera of a VTK view into this frame
with :meth:`Camera.transformed`, so the cores never deal with origin or direction cosines.

Conventions follow ``vtkCamera``: ``view_angle`` is the full *vertical* field of view in degrees,
``parallel_scale`` is half the viewport height in world units, the image aspect is ``width / height``, and pixel
``(col, row)`` has its centre at normalised device coordinates ``((col + 0.5) / width * 2 - 1,
(row + 0.5) / height * 2 - 1)`` with ``row`` counted from the *bottom*. Images returned by our renderers are
``(height, width, channels)`` arrays with row 0 at the *top* (like PNG files); :meth:`Camera.pixel_rays` follows
that order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .validation import validated_image_size


def _vec(value) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"camera vectors must be finite, got {value!r}")
    return array


@dataclass(frozen=True)
class Camera:
    """Position, focal point, view up and projection of a pinhole or parallel camera.

    Parameters
    ----------
    position, focal_point, view_up : sequence of 3 floats
        As in ``vtkCamera``. ``view_up`` need not be orthogonal to the view direction; it is re-orthogonalised.
    view_angle : float
        Full vertical field of view in degrees (perspective only).
    parallel_projection : bool
        Parallel (orthographic) projection when true.
    parallel_scale : float
        Half the height of the viewport in world units (parallel only).
    """

    position: tuple[float, float, float]
    focal_point: tuple[float, float, float]
    view_up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    view_angle: float = 30.0
    parallel_projection: bool = False
    parallel_scale: float = 1.0

    def __post_init__(self) -> None:
        position, focal, up = _vec(self.position), _vec(self.focal_point), _vec(self.view_up)
        if np.linalg.norm(focal - position) == 0:
            raise ValueError("camera position and focal point coincide")
        forward = (focal - position) / np.linalg.norm(focal - position)
        if np.linalg.norm(np.cross(forward, up)) < 1e-9:
            raise ValueError("camera view up is parallel to the viewing direction")
        if not (0.0 < self.view_angle < 180.0):
            raise ValueError(f"view_angle must lie in (0, 180) degrees, got {self.view_angle}")
        if self.parallel_scale <= 0:
            raise ValueError(f"parallel_scale must be positive, got {self.parallel_scale}")
        object.__setattr__(self, "position", tuple(position))
        object.__setattr__(self, "focal_point", tuple(focal))
        object.__setattr__(self, "view_up", tuple(up))

    # -- frames -----------------------------------------------------------------------------------------------
    @property
    def direction(self) -> np.ndarray:
        """Unit direction of projection (from the position towards the focal point)."""
        d = np.subtract(self.focal_point, self.position)
        return d / np.linalg.norm(d)

    @property
    def distance(self) -> float:
        return float(np.linalg.norm(np.subtract(self.focal_point, self.position)))

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal ``(right, up, forward)``; ``right = forward x up`` as on screen."""
        forward = self.direction
        right = np.cross(forward, self.view_up)
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return right, up, forward

    def view_matrix(self) -> np.ndarray:
        """4x4 world-to-eye matrix (eye looks down -z, like OpenGL and VTK)."""
        right, up, forward = self.basis()
        rotation = np.stack([right, up, -forward])
        matrix = np.eye(4)
        matrix[:3, :3] = rotation
        matrix[:3, 3] = -rotation @ np.asarray(self.position)
        return matrix

    def half_extents(self, width: int, height: int) -> tuple[float, float]:
        """Half width and half height of the image plane at unit distance (perspective) or in world units."""
        aspect = width / height
        half_h = self.parallel_scale if self.parallel_projection else math.tan(math.radians(self.view_angle) / 2)
        return half_h * aspect, half_h

    # -- rays ---------------------------------------------------------------------------------------------
    def ray_frame(self, width: int, height: int) -> np.ndarray:
        """The five 3-vectors a kernel needs to build the ray of any pixel, as a ``(5, 3)`` float64 array.

        Rows: ``origin0``, ``direction0`` (ray of the centre of the top-left pixel), ``d_col``, ``d_row``
        (change per pixel column / row, rows going down), and ``forward``. For a perspective camera the origin
        is fixed and the (unnormalised) direction changes: ``dir = direction0 + col * d_col + row * d_row``;
        for a parallel camera the direction is fixed and the origin changes:
        ``origin = origin0 + col * d_col + row * d_row``.
        """
        width, height = validated_image_size(width, height)
        right, up, forward = self.basis()
        half_w, half_h = self.half_extents(width, height)
        d_col = right * (2.0 * half_w / width)
        d_row = -up * (2.0 * half_h / height)
        top_left = -right * half_w + up * half_h + 0.5 * d_col + 0.5 * d_row
        position = np.asarray(self.position)
        if self.parallel_projection:
            return np.stack([position + top_left, forward, d_col, d_row, forward])
        return np.stack([position, forward + top_left, d_col, d_row, forward])

    def pixel_rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions of every pixel's ray, each ``(height, width, 3)``, row 0 at the top."""
        frame = self.ray_frame(width, height)
        cols = np.arange(width, dtype=np.float64)[None, :, None]
        rows = np.arange(height, dtype=np.float64)[:, None, None]
        offsets = cols * frame[2] + rows * frame[3]
        if self.parallel_projection:
            origins = frame[0] + offsets
            directions = np.broadcast_to(frame[1], origins.shape).copy()
        else:
            directions = frame[1] + offsets
            directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
            origins = np.broadcast_to(frame[0], directions.shape).copy()
        return origins, directions

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """Pixel coordinates ``(col, row)`` (row 0 at the top, pixel centres at .5) of world points ``(n, 3)``."""
        points = np.atleast_2d(np.asarray(points, dtype=np.float64))
        right, up, forward = self.basis()
        rel = points - np.asarray(self.position)
        x, y, z = rel @ right, rel @ up, rel @ forward
        half_w, half_h = self.half_extents(width, height)
        if not self.parallel_projection:
            x, y = x / z, y / z
        col = (x / half_w + 1.0) * 0.5 * width
        row = (1.0 - y / half_h) * 0.5 * height
        return np.stack([col, row], axis=-1)

    # -- changes ------------------------------------------------------------------------------------------
    def transformed(self, matrix: np.ndarray) -> "Camera":
        """The same camera expressed through the affine 4x4 ``matrix`` (applied to points).

        The matrix must be a rigid motion (rotation + translation) for the projection to be preserved; a uniform
        scale also scales ``parallel_scale``.
        """
        matrix = np.asarray(matrix, dtype=np.float64)
        linear = matrix[:3, :3]
        scale = abs(np.linalg.det(linear)) ** (1.0 / 3.0)
        if not np.allclose(linear.T @ linear, np.eye(3) * scale**2, atol=1e-6 * max(1.0, scale**2)):
            raise ValueError("the camera can only be moved by a rotation, translation and uniform scale")
        position = linear @ np.asarray(self.position) + matrix[:3, 3]
        focal = linear @ np.asarray(self.focal_point) + matrix[:3, 3]
        up = linear @ np.asarray(self.view_up)
        return replace(
            self,
            position=tuple(position),
            focal_point=tuple(focal),
            view_up=tuple(up / np.linalg.norm(up)),
            parallel_scale=self.parallel_scale * scale,
        )

    def as_parallel(self) -> "Camera":
        """The parallel camera that shows the focal plane as this one does (same pose and framing there)."""
        if self.parallel_projection:
            return self
        scale = self.distance * math.tan(math.radians(self.view_angle) / 2)
        return replace(self, parallel_projection=True, parallel_scale=scale)

    def orbited(self, azimuth: float = 0.0, elevation: float = 0.0) -> "Camera":
        """Rotate the position about the focal point like ``vtkCamera.Azimuth`` then ``Elevation`` (degrees)."""
        right, up, forward = self.basis()
        focal = np.asarray(self.focal_point)
        rel = np.asarray(self.position) - focal
        rel = _rotate(rel, up, azimuth)
        new_forward = -rel / np.linalg.norm(rel)
        axis = np.cross(new_forward, up)  # the new right-hand vector (VTK rotates about it)
        rel = _rotate(rel, axis / np.linalg.norm(axis), -elevation)
        view_up = _rotate(up, axis / np.linalg.norm(axis), -elevation)
        return replace(self, position=tuple(focal + rel), view_up=tuple(view_up))

    # -- VTK --------------------------------------------------------------------------------------------
    @classmethod
    def from_vtk(cls, vtk_camera) -> "Camera":
        """Copy a ``vtkCamera``."""
        return cls(
            position=vtk_camera.GetPosition(),
            focal_point=vtk_camera.GetFocalPoint(),
            view_up=vtk_camera.GetViewUp(),
            view_angle=vtk_camera.GetViewAngle(),
            parallel_projection=bool(vtk_camera.GetParallelProjection()),
            parallel_scale=vtk_camera.GetParallelScale(),
        )

    def apply_to_vtk(self, vtk_camera) -> None:
        """Set a ``vtkCamera`` to this camera (clipping range is left to the renderer)."""
        vtk_camera.SetPosition(*self.position)
        vtk_camera.SetFocalPoint(*self.focal_point)
        vtk_camera.SetViewUp(*self.view_up)
        vtk_camera.SetViewAngle(self.view_angle)
        vtk_camera.SetParallelProjection(int(self.parallel_projection))
        vtk_camera.SetParallelScale(self.parallel_scale)


def checked_camera(camera) -> Camera:
    """``camera`` itself if it is a :class:`Camera`; a TypeError naming what it is otherwise."""
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be an algorithms.common.camera.Camera, got {type(camera).__name__}")
    return camera


def _rotate(vector: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """Rodrigues rotation of ``vector`` about unit ``axis`` by ``degrees`` (right-handed)."""
    theta = math.radians(degrees)
    axis = axis / np.linalg.norm(axis)
    return (
        vector * math.cos(theta)
        + np.cross(axis, vector) * math.sin(theta)
        + axis * np.dot(axis, vector) * (1 - math.cos(theta))
    )


def box_ray_intersection(
    origins: np.ndarray, directions: np.ndarray, box_min, box_max
) -> tuple[np.ndarray, np.ndarray]:
    """Slab test: entry and exit parameters ``t`` of rays with an axis-aligned box (``t_exit < t_entry``: miss).

    ``origins`` and ``directions`` are ``(..., 3)``; the result has shape ``(...)``. Entry is clamped at 0 so a
    ray starting inside the box enters at its origin.
    """
    box_min = np.asarray(box_min, dtype=np.float64)
    box_max = np.asarray(box_max, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / directions
        t0 = (box_min - origins) * inverse
        t1 = (box_max - origins) * inverse
    t_near = np.where(np.isnan(t0), -np.inf, np.minimum(t0, t1)).max(axis=-1)
    t_far = np.where(np.isnan(t1), np.inf, np.maximum(t0, t1)).min(axis=-1)
    return np.maximum(t_near, 0.0), t_far
