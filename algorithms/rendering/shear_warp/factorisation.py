"""The affine shear-warp factorisation of a parallel view, ``M_view = M_warp2D * M_shear * P`` (source 004, 4.2).

See :mod:`algorithms.rendering.shear_warp` for the method. Object coordinates are voxel indices (voxel
``[k, j, i]`` of a ``(nz, ny, nx)`` array at ``(x, y, z) = (i, j, k)``); standard coordinates ``(i, j, k)`` have
``k`` along the principal viewing axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...common.camera import Camera
from ...common.validation import validated_image_size, validated_shape, validated_spacing

#: Object axes (0 = x/i, 1 = y/j, 2 = z/k of the volume) that become the standard axes (i, j, k), per principal
#: axis: cyclic permutations, so the standard frame is right-handed like the object frame.
STANDARD_AXES = ((1, 2, 0), (2, 0, 1), (0, 1, 2))
AXIS_NAMES = ("x", "y", "z")
#: Offsets closer than this (voxels) to an integer are snapped to it, so axis-aligned views resample exactly.
_SNAP = 1e-9


def view_matrix(camera: Camera, spacing: Sequence[float], width: int, height: int) -> np.ndarray:
    """``M_view``: the 4x4 transformation from object coordinates ``(x, y, z, 1)`` to ``(col, row, depth, 1)``.

    Object coordinates are voxel indices (voxel ``[k, j, i]`` of the array is at ``(x, y, z) = (i, j, k)``);
    ``col``/``row`` are the pixel coordinates of :meth:`Camera.project` (row 0 at the top, pixel centres at .5) of
    the point ``(x sx, y sy, z sz)`` mm, and ``depth`` its distance in mm in front of the camera plane. Affine for a
    parallel camera; for a perspective camera it is the transformation before the division by depth.
    """
    right, up, forward = camera.basis()
    half_w, half_h = camera.half_extents(width, height)
    position = np.asarray(camera.position)
    scale = np.asarray(spacing, dtype=np.float64)
    col_scale = width / (2.0 * half_w)
    row_scale = height / (2.0 * half_h)
    matrix = np.eye(4)
    matrix[0, :3] = col_scale * right * scale
    matrix[0, 3] = width / 2.0 - col_scale * (right @ position)
    matrix[1, :3] = -row_scale * up * scale
    matrix[1, 3] = height / 2.0 + row_scale * (up @ position)
    matrix[2, :3] = forward * scale
    matrix[2, 3] = -(forward @ position)
    return matrix


def standard_order(array: np.ndarray, principal_axis: int) -> np.ndarray:
    """A ``(nz, ny, nx)`` array seen in standard order ``[k, j, i]`` for ``principal_axis`` (a transposed view)."""
    axis_i, axis_j, axis_k = STANDARD_AXES[principal_axis]
    return np.asarray(array).transpose(2 - axis_k, 2 - axis_j, 2 - axis_i)


@dataclass(frozen=True)
class Factorization:
    """The affine shear-warp factorisation ``view = warp2D * shear * permutation`` of one parallel view.

    Attributes
    ----------
    principal_axis : int
        Object axis most parallel to the viewing direction: 0 = x (i), 1 = y (j), 2 = z (k).
    permutation : ndarray (4, 4)
        ``P``: object voxel coordinates ``(x, y, z, 1)`` to standard coordinates ``(i, j, k, 1)``.
    shear : (float, float)
        ``(s_i, s_j)``: translation of slice ``k`` per unit of ``k``, in voxels.
    translation : (float, float)
        ``(t_i, t_j)``: moves the intermediate image's origin to its top-left corner.
    slice_step : int
        +1 when slice 0 is in front (slices are composited in ascending ``k``), -1 otherwise.
    view : ndarray (4, 4)
        :func:`view_matrix` of the camera: object voxel coordinates to ``(col, row, depth, 1)``.
    warp : ndarray (3, 3)
        ``M_warp2D``: intermediate image ``(u, v, 1)`` (pixel centres at integers) to final ``(col, row, 1)``.
    standard_shape : (int, int, int)
        ``(nk, nj, ni)``: the volume's shape in standard order.
    intermediate_shape : (int, int)
        ``(height, width)`` of the intermediate image.
    sample_distance : float
        Distance in mm between the samples of one ray in consecutive slices (the opacity correction's ``dx``).
    """

    principal_axis: int
    permutation: np.ndarray
    shear: tuple[float, float]
    translation: tuple[float, float]
    slice_step: int
    view: np.ndarray
    warp: np.ndarray
    standard_shape: tuple[int, int, int]
    intermediate_shape: tuple[int, int]
    sample_distance: float

    @property
    def shear_matrix(self) -> np.ndarray:
        """``M_shear`` (4x4): standard coordinates ``(i, j, k, 1)`` to intermediate ``(u, v, k, 1)``."""
        (s_i, s_j), (t_i, t_j) = self.shear, self.translation
        return np.array([[1.0, 0.0, s_i, t_i], [0.0, 1.0, s_j, t_j], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])

    @property
    def slice_order(self) -> np.ndarray:
        """Slice indices ``k`` front to back, int64."""
        nk = self.standard_shape[0]
        order = np.arange(nk, dtype=np.int64)
        return order if self.slice_step > 0 else order[::-1].copy()

    def slice_offsets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Where each slice lands on the intermediate image, and its bilinear weights (computed once per slice).

        Slice ``k`` is translated by ``o = s k + t`` (per axis). With ``p = ceil(o)`` and ``f = p - o`` in
        ``[0, 1)``, intermediate pixel ``u`` samples the slice at ``i = (u - p) + f``: voxel ``u - p`` with weight
        ``1 - f`` and voxel ``u - p + 1`` with weight ``f``. Returns ``(p_i, p_j, f_i, f_j)``, each of length
        ``nk`` (int64, int64, float64, float64).
        """
        nk = self.standard_shape[0]
        pixel_i, fraction_i = _slice_offsets(self.shear[0], self.translation[0], nk)
        pixel_j, fraction_j = _slice_offsets(self.shear[1], self.translation[1], nk)
        return pixel_i, pixel_j, fraction_i, fraction_j


def _slice_offsets(shear: float, translation: float, nk: int) -> tuple[np.ndarray, np.ndarray]:
    """``(ceil(o), ceil(o) - o)`` of the offsets ``o = shear * k + translation`` of slices ``k = 0 .. nk - 1``."""
    offset = shear * np.arange(nk, dtype=np.float64) + translation
    nearest = np.rint(offset)
    offset = np.where(np.abs(offset - nearest) < _SNAP, nearest, offset)
    pixel = np.ceil(offset)
    return pixel.astype(np.int64), pixel - offset


def factorize(camera: Camera, shape: Sequence[int], spacing: Sequence[float], width: int, height: int) -> Factorization:
    """Factor the view of a parallel ``camera`` on a volume of ``shape`` ``(nz, ny, nx)`` (source 004, 4.2).

    Parameters
    ----------
    camera : Camera
        Parallel camera in the volume frame (mm).
    shape : (nz, ny, nx)
        Volume shape, at least 2 voxels along every axis.
    spacing : (sx, sy, sz)
        Voxel size in mm.
    width, height : int
        Final image size in pixels.

    Returns
    -------
    Factorization

    Raises
    ------
    ValueError
        For a perspective camera (only the affine factorisation is implemented), a bad shape, spacing or size.
    """
    if not isinstance(camera, Camera):
        raise ValueError(f"camera must be an algorithms.common.camera.Camera, got {type(camera).__name__}")
    if not camera.parallel_projection:
        raise ValueError(
            "shear-warp here factors parallel projections only; the perspective shear-warp factorisation "
            "(Lacroute 1995) is not implemented: use a camera with parallel_projection=True"
        )
    nz, ny, nx = validated_shape(shape, min_size=2)
    spacing = tuple(validated_spacing(spacing))
    width, height = validated_image_size(width, height)

    view = view_matrix(camera, spacing, width, height)
    # Viewing direction in object coordinates: orthogonal to both image-plane rows (Cramer's rule, 4.2.2.1),
    # oriented away from the camera (increasing depth).
    direction = np.cross(view[0, :3], view[1, :3])
    if direction @ view[2, :3] < 0:
        direction = -direction
    principal = int(np.argmax(np.abs(direction)))
    axes = STANDARD_AXES[principal]
    permutation = np.zeros((4, 4))
    permutation[3, 3] = 1.0
    for row, axis in enumerate(axes):
        permutation[row, axis] = 1.0
    standard_view = view @ permutation.T  # M' = M P^-1 (P is orthogonal)
    v_i, v_j, v_k = permutation[:3, :3] @ direction
    s_i, s_j = -v_i / v_k, -v_j / v_k
    sizes = (nx, ny, nz)
    ni, nj, nk = (sizes[a] for a in axes)
    k_max = nk - 1
    t_i = 0.0 if s_i >= 0 else -s_i * k_max
    t_j = 0.0 if s_j >= 0 else -s_j * k_max
    m = standard_view
    warp = np.array(
        [
            [m[0, 0], m[0, 1], m[0, 3] - t_i * m[0, 0] - t_j * m[0, 1]],
            [m[1, 0], m[1, 1], m[1, 3] - t_i * m[1, 0] - t_j * m[1, 1]],
            [0.0, 0.0, 1.0],
        ]
    )
    # One slice further along a ray: (-s_i, -s_j, 1) in standard coordinates, back to object voxels, then mm.
    step_object = permutation[:3, :3].T @ np.array([-s_i, -s_j, 1.0])
    pixel_i, _ = _slice_offsets(s_i, t_i, nk)
    pixel_j, _ = _slice_offsets(s_j, t_j, nk)
    return Factorization(
        principal_axis=principal,
        permutation=permutation,
        shear=(float(s_i), float(s_j)),
        translation=(float(t_i), float(t_j)),
        slice_step=1 if v_k > 0 else -1,
        view=view,
        warp=warp,
        standard_shape=(nk, nj, ni),
        intermediate_shape=(nj + int(pixel_j.max()), ni + int(pixel_i.max())),
        sample_distance=float(np.linalg.norm(step_object * spacing)),
    )
