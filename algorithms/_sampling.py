"""Sampling a volume, shared by the software renderers (ray marching, texture slicing): validation of the inputs,
and numba kernels for trilinear interpolation and central-difference gradients.

Index coordinates: voxel ``(i, j, k)`` sits at ``(x, y, z) = (i, j, k)``; the array is ``(nz, ny, nx)``, indexed
``[k, j, i]``. Values outside the volume are those of the nearest edge voxel (clamp to edge, like an OpenGL 3D
texture with ``GL_CLAMP_TO_EDGE``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


def validated_volume(volume_array) -> np.ndarray:
    """A read-only float32 C-ordered copy of a real-valued ``(nz, ny, nx)`` volume with >= 2 voxels per axis."""
    array = np.asarray(volume_array)
    if array.ndim != 3:
        raise ValueError(f"expected a 3D volume (nz, ny, nx), got an array of shape {array.shape}")
    if min(array.shape) < 2:
        raise ValueError(f"the volume needs at least 2 voxels along every axis to span a box, got shape {array.shape}")
    if array.dtype == np.bool_:
        array = array.astype(np.uint8)
    if array.dtype.kind not in "iuf":
        raise ValueError(f"expected a real-valued volume, got dtype {array.dtype}")
    # A private copy: the min-max bricks describe these values, so the caller must not be able to change them.
    volume = np.array(array, dtype=np.float32, order="C", copy=True)
    if array.dtype.kind == "f" and not np.all(np.isfinite(volume)):
        raise ValueError("the volume contains NaN or infinite values")
    volume.setflags(write=False)
    return volume


def validated_spacing(spacing) -> np.ndarray:
    """``(sx, sy, sz)`` as a float64 array of three positive finite millimetre values."""
    try:
        values = np.array([float(s) for s in spacing], dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"spacing must be three positive millimetre values (x, y, z), got {spacing!r}") from None
    if values.shape != (3,) or not np.all(np.isfinite(values)) or values.min() <= 0:
        raise ValueError(f"spacing must be three positive millimetre values (x, y, z), got {spacing!r}")
    return values


@njit(cache=True, nogil=True)
def _cell(coordinate, size):
    """Lower cell index and fraction of an index coordinate, clamped to the volume (clamp-to-edge)."""
    if coordinate <= 0.0:
        return 0, 0.0
    if coordinate >= size - 1:
        return size - 2, 1.0
    index = min(int(coordinate), size - 2)
    return index, coordinate - index


@njit(cache=True, nogil=True)
def _trilinear(volume, i0, j0, k0, fx, fy, fz):
    """Trilinear interpolation in the cell with lower corner ``(i0, j0, k0)`` at fractions ``(fx, fy, fz)``."""
    c000 = volume[k0, j0, i0]
    c001 = volume[k0, j0, i0 + 1]
    c010 = volume[k0, j0 + 1, i0]
    c011 = volume[k0, j0 + 1, i0 + 1]
    c100 = volume[k0 + 1, j0, i0]
    c101 = volume[k0 + 1, j0, i0 + 1]
    c110 = volume[k0 + 1, j0 + 1, i0]
    c111 = volume[k0 + 1, j0 + 1, i0 + 1]
    c00 = c000 + fx * (c001 - c000)
    c01 = c010 + fx * (c011 - c010)
    c10 = c100 + fx * (c101 - c100)
    c11 = c110 + fx * (c111 - c110)
    c0 = c00 + fy * (c01 - c00)
    c1 = c10 + fy * (c11 - c10)
    return c0 + fz * (c1 - c0)


@njit(cache=True, nogil=True)
def sample_volume(volume, x, y, z):
    """The trilinearly interpolated value at index coordinates ``(x, y, z)`` (clamped to the volume)."""
    nz, ny, nx = volume.shape
    i0, fx = _cell(x, nx)
    j0, fy = _cell(y, ny)
    k0, fz = _cell(z, nz)
    return _trilinear(volume, i0, j0, k0, fx, fy, fz)


@njit(cache=True, nogil=True)
def gradient(volume, x, y, z, sx, sy, sz):
    """Central-difference gradient (value units per mm) of the interpolated field at index ``(x, y, z)``.

    Differences span one voxel on either side along each axis, as VTK's GPU ray caster and source 002 (2.4.4) do.
    """
    gx = (sample_volume(volume, x + 1.0, y, z) - sample_volume(volume, x - 1.0, y, z)) / (2.0 * sx)
    gy = (sample_volume(volume, x, y + 1.0, z) - sample_volume(volume, x, y - 1.0, z)) / (2.0 * sy)
    gz = (sample_volume(volume, x, y, z + 1.0) - sample_volume(volume, x, y, z - 1.0)) / (2.0 * sz)
    return gx, gy, gz
