"""Sampling a volume, shared by the software renderers (ray marching, texture slicing, shear-warp): numba kernels
for trilinear interpolation and central-difference gradients (their inputs are checked by
:func:`algorithms.common.validation.validated_float_volume` and ``validated_spacing``), and the per-pixel jitter
of the first sample along each ray.

Jitter (Engel et al., *Real-Time Volume Graphics*, 2006, section 9.1.7; the interleaved gradient noise of J.
Jimenez, *Next generation post processing in Call of Duty: Advanced Warfare*, SIGGRAPH 2014 course): a ray marched
with a fixed step from the box entry samples every ray at the same depths, so a smooth surface crossed at a
slant is reconstructed at quantised depths and draws concentric rings ("wood grain"). Shifting each pixel's first
sample by a fraction ``j`` of the step, with ``j`` from an interleaved pattern that differs between neighbouring
pixels, turns the rings into fine, high-frequency noise. The pattern is a pure function of the pixel (and of a
pass index), so a still image does not flicker and the same camera and size give the same frame; successive passes
add the golden ratio to ``j`` (a rank-1 lattice in time), so averaging passes converges evenly.

The volume may be of any real dtype (numba specialises the kernels; values are converted to float on reading).

Index coordinates: voxel ``(i, j, k)`` sits at ``(x, y, z) = (i, j, k)``; the array is ``(nz, ny, nx)``, indexed
``[k, j, i]``. Values outside the volume are those of the nearest edge voxel (clamp to edge, like an OpenGL 3D
texture with ``GL_CLAMP_TO_EDGE``).
"""

from __future__ import annotations

import math

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
def blend_corners(c000, c001, c010, c011, c100, c101, c110, c111, fx, fy, fz):
    """Trilinear blend of a cell's eight corner values (``cKJI``: corner at ``k0 + K``, ``j0 + J``, ``i0 + I``) at
    fractions ``(fx, fy, fz)``: along x, then y, then z. Every trilinear read (volumes, grid cut-away tools) ends
    here."""
    c00 = c000 + fx * (c001 - c000)
    c01 = c010 + fx * (c011 - c010)
    c10 = c100 + fx * (c101 - c100)
    c11 = c110 + fx * (c111 - c110)
    c0 = c00 + fy * (c01 - c00)
    c1 = c10 + fy * (c11 - c10)
    return c0 + fz * (c1 - c0)


@njit(cache=True, nogil=True)
def trilinear(volume, i0, j0, k0, fx, fy, fz):
    """Trilinear interpolation in the cell with lower corner ``(i0, j0, k0)`` at fractions ``(fx, fy, fz)``."""
    return blend_corners(
        volume[k0, j0, i0], volume[k0, j0, i0 + 1], volume[k0, j0 + 1, i0], volume[k0, j0 + 1, i0 + 1],
        volume[k0 + 1, j0, i0], volume[k0 + 1, j0, i0 + 1], volume[k0 + 1, j0 + 1, i0], volume[k0 + 1, j0 + 1, i0 + 1],
        fx, fy, fz)


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


#: Golden ratio conjugate: the offset of successive jitter passes (the additive recurrence with the best spread).
_GOLDEN = 0.6180339887498949
#: sqrt(2) - 1: the pass offset of a second, independent jitter (with the golden ratio a 2D Kronecker sequence).
_SILVER = 0.41421356237309503


@njit(cache=True, nogil=True, forceinline=True)
def jitter_offset(col, row, pass_index):
    """The jitter ``j`` in [0, 1) of pixel ``(col, row)`` in accumulation pass ``pass_index`` (0 for a still frame).

    Interleaved gradient noise (Jimenez 2014): ``fract(52.9829189 * fract(0.06711056 x + 0.00583715 y))``, which
    gives every 3 x 3 block of pixels nearly all offsets (blue-noise-like, no low-frequency pattern), plus
    ``pass_index`` times the golden ratio conjugate.
    """
    value = 0.06711056 * col + 0.00583715 * row
    value = 52.9829189 * (value - math.floor(value))
    value = value - math.floor(value) + _GOLDEN * pass_index
    return value - math.floor(value)


@njit(cache=True, nogil=True, forceinline=True)
def second_jitter_offset(col, row, pass_index):
    """A second jitter in [0, 1) of pixel ``(col, row)``, independent of :func:`jitter_offset` (for a second
    sampling decision of the same ray, such as where the light march starts): the same noise on transposed,
    shifted coordinates, advancing by ``sqrt(2) - 1`` per pass so that the pair of offsets fills the unit square
    over passes instead of moving along a line."""
    value = 0.06711056 * (row + 37.0) + 0.00583715 * (col + 11.0)
    value = 52.9829189 * (value - math.floor(value))
    value = value - math.floor(value) + _SILVER * pass_index
    return value - math.floor(value)


def jitter_pattern(width: int, height: int, pass_index: int = 0):
    """:func:`jitter_offset` of every pixel as a ``(height, width)`` float64 array (row 0 at the top)."""
    import numpy as np

    cols = np.arange(width, dtype=np.float64)[None, :]
    rows = np.arange(height, dtype=np.float64)[:, None]
    value = 0.06711056 * cols + 0.00583715 * rows
    value = 52.9829189 * (value - np.floor(value))
    value = value - np.floor(value) + _GOLDEN * pass_index
    return value - np.floor(value)


def sampled_volume(volume):
    """The array a renderer samples, kept for as long as the renderer lives: ``volume`` itself when it is already a
    read-only, native-order, C-contiguous array of a kernel dtype (nobody can change the values the set-up
    describes, so no copy is needed: a 512^3 int16 volume costs no second 256 MiB), else a private read-only copy
    in the volume's own dtype (booleans as uint8, float16 as float32). Values are converted to float when sampled.

    Raises ValueError for a volume that is not 3D, has fewer than 2 voxels along an axis, is not real-valued, or
    holds NaN or infinity.
    """
    import numpy as np

    from .validation import validated_numeric_volume

    original = np.asarray(volume)
    array = validated_numeric_volume(original, min_size=2, finite=True)
    if not array.flags.writeable and np.shares_memory(array, original):
        return array  # read-only, already in a kernel's form: a view of the caller's memory
    copy = np.array(array, order="C", copy=True)
    copy.setflags(write=False)
    return copy
