"""Sampling a volume, shared by the software renderers (ray marching, texture slicing): numba kernels for
trilinear interpolation and central-difference gradients (their inputs are checked by
:func:`algorithms.common.validation.validated_float_volume` and ``validated_spacing``).

Index coordinates: voxel ``(i, j, k)`` sits at ``(x, y, z) = (i, j, k)``; the array is ``(nz, ny, nx)``, indexed
``[k, j, i]``. Values outside the volume are those of the nearest edge voxel (clamp to edge, like an OpenGL 3D
texture with ``GL_CLAMP_TO_EDGE``).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def cell_of(coordinate, size):
    """Lower cell index and fraction of an index coordinate, clamped to the volume (clamp-to-edge)."""
    if coordinate <= 0.0:
        return 0, 0.0
    if coordinate >= size - 1:
        return size - 2, 1.0
    index = min(int(coordinate), size - 2)
    return index, coordinate - index


@njit(cache=True, nogil=True)
def trilinear(volume, i0, j0, k0, fx, fy, fz):
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
    i0, fx = cell_of(x, nx)
    j0, fy = cell_of(y, ny)
    k0, fz = cell_of(z, nz)
    return trilinear(volume, i0, j0, k0, fx, fy, fz)


@njit(cache=True, nogil=True)
def gradient(volume, x, y, z, sx, sy, sz):
    """Central-difference gradient (value units per mm) of the interpolated field at index ``(x, y, z)``.

    Differences span one voxel on either side along each axis, as VTK's GPU ray caster and source 002 (Kähler,
    *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009), section 2.4.4, do.
    """
    gx = (sample_volume(volume, x + 1.0, y, z) - sample_volume(volume, x - 1.0, y, z)) / (2.0 * sx)
    gy = (sample_volume(volume, x, y + 1.0, z) - sample_volume(volume, x, y - 1.0, z)) / (2.0 * sy)
    gz = (sample_volume(volume, x, y, z + 1.0) - sample_volume(volume, x, y, z - 1.0)) / (2.0 * sz)
    return gx, gy, gz
