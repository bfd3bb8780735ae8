"""Encoding a principal axis's copy straight from the scalar volume, resampled on the fly (numba).

The classified, run-length encoded copy of one principal axis (source 004, section 5.2.2; layout in
:mod:`.kernels`) is built here without any volume-sized intermediate array: every voxel of the *rendered grid* is
read from the scalar volume, classified through the transfer function (nearest table entry) and, with shading,
given its quantised normal (section 5.2.7), scanline by scanline, in two passes (count the runs, then fill them).
So the only memory a copy costs is what it stores, and the copies are built when a view first needs them.

The rendered grid is the volume's own grid, or a finer one along coarse axes: source 004 (section 6.3.1)
recommends resampling anisotropic volumes before shear-warp, since the intermediate image has one pixel per voxel
and a 2 mm slice spacing stays 2 mm wide on it. Grid point ``p`` of an axis with ``m`` points over a volume axis of
``n`` voxels lies at index ``p (n - 1) / (m - 1)``; values there are trilinear (linear along each resampled axis,
exact voxel values along the others), and normals are central differences one rendered voxel wide (of the
trilinear field), so they do not depend on which principal axis is encoded.

Axis order: the volume is ``(nz, ny, nx)``; a copy is in standard order ``[k, j, i]`` of its principal axis
(``STANDARD_AXES`` in :mod:`.factorisation`: object axes ``(axis_i, axis_j, axis_k)``).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ...common.sampling import sample_volume


@njit(cache=True, nogil=True, inline="always")
def _coordinate(axis, i, j, k, axes, scales):
    """Index coordinate along object ``axis`` of rendered-grid point ``(i, j, k)`` of the standard order with
    object axes ``axes`` (``axes[0]`` is the object axis of ``i``)."""
    if axes[0] == axis:
        return i * scales[axis]
    if axes[1] == axis:
        return j * scales[axis]
    return k * scales[axis]


@njit(cache=True, nogil=True, inline="always")
def _object_point(i, j, k, axes, scales):
    """Index coordinates ``(x, y, z)`` in the scalar volume of rendered-grid point ``(i, j, k)``."""
    return (_coordinate(0, i, j, k, axes, scales), _coordinate(1, i, j, k, axes, scales),
            _coordinate(2, i, j, k, axes, scales))


@njit(cache=True, nogil=True, inline="always")
def _value(volume, x, y, z, resampled):
    if resampled:
        return np.float64(sample_volume(volume, x, y, z))
    return np.float64(volume[int(z), int(y), int(x)])


@njit(cache=True, nogil=True, forceinline=True)
def _class_of(value, value_min, scale, last_entry):
    position = (value - value_min) * scale
    if position <= 0.0:
        return 0
    if position >= last_entry:
        return last_entry
    return np.int64(position + 0.5)


@njit(cache=True, nogil=True, inline="always")
def _difference(volume, x, y, z, axis, step, size, spacing, resampled):
    """Central difference quotient (value per mm) along ``axis`` at ``(x, y, z)``, ``step`` indices to either
    side, one-sided at the box; 0 on a one-voxel axis."""
    centre = x if axis == 0 else (y if axis == 1 else z)
    low = max(centre - step, 0.0)
    high = min(centre + step, size - 1.0)
    if not high > low:
        return 0.0
    if axis == 0:
        difference = _value(volume, high, y, z, resampled) - _value(volume, low, y, z, resampled)
    elif axis == 1:
        difference = _value(volume, x, high, z, resampled) - _value(volume, x, low, z, resampled)
    else:
        difference = _value(volume, x, y, high, resampled) - _value(volume, x, y, low, resampled)
    return difference / ((high - low) * spacing)


@njit(cache=True, nogil=True)
def _normal_index(volume, x, y, z, steps, spacing, resampled, encoding, half_grid, zero_index):
    """Quantised normal (``-grad / |grad|``, see :func:`.kernels.normal_indices`) at index point ``(x, y, z)``:
    central differences ``steps`` (one rendered voxel, in volume indices) to either side, one-sided at the box."""
    # One call in a loop over the axes, not one per axis: numba inlines each call of _difference (and its calls of
    # _value) as a copy of its code.
    gx = gy = gz = 0.0
    for axis in range(3):
        g = _difference(volume, x, y, z, axis, steps[axis], volume.shape[2 - axis], spacing[axis], resampled)
        if axis == 0:
            gx = g
        elif axis == 1:
            gy = g
        else:
            gz = g
    norm = np.sqrt(gx * gx + gy * gy + gz * gz)
    if norm == 0.0:
        return zero_index
    vx = np.int64(np.rint(half_grid - half_grid * gx / norm))
    vy = np.int64(np.rint(half_grid - half_grid * gy / norm))
    hemisphere = 0 if gz <= 0.0 else 1
    return encoding[hemisphere, vx, vy]


@njit(cache=True, nogil=True, parallel=True)
def count_runs_resampled(volume, axes, shape, scales, resampled, value_min, scale, last_entry, visible):
    """Runs and non-transparent voxels of every scanline ``(k, j)`` of the rendered grid in standard order
    ``shape = (nk, nj, ni)`` (see :func:`.kernels.count_runs`)."""
    nk, nj, ni = shape[0], shape[1], shape[2]
    runs = np.empty(nk * nj, dtype=np.int64)
    voxels = np.empty(nk * nj, dtype=np.int64)
    for k in prange(nk):
        for j in range(nj):
            n_runs = 1
            n_voxels = 0
            current = False
            for i in range(ni):
                x, y, z = _object_point(i, j, k, axes, scales)
                shown = visible[_class_of(_value(volume, x, y, z, resampled), value_min, scale, last_entry)]
                if shown != current:
                    n_runs += 1
                    current = shown
                if shown:
                    n_voxels += 1
            runs[k * nj + j] = n_runs
            voxels[k * nj + j] = n_voxels
    return runs, voxels


@njit(cache=True, nogil=True, parallel=True)
def fill_runs_resampled(volume, axes, shape, scales, resampled, value_min, scale, last_entry, visible, spacing,
                        with_normals, encoding, half_grid, zero_index, line_runs, line_voxels, run_lengths,
                        voxel_classes, voxel_normals):
    """Write the runs, classes and (``with_normals``) normal indices of :func:`count_runs_resampled`'s grid."""
    nk, nj, ni = shape[0], shape[1], shape[2]
    for k in prange(nk):
        for j in range(nj):
            run = line_runs[k * nj + j]
            voxel = line_voxels[k * nj + j]
            current = False
            length = 0
            for i in range(ni):
                x, y, z = _object_point(i, j, k, axes, scales)
                entry = _class_of(_value(volume, x, y, z, resampled), value_min, scale, last_entry)
                shown = visible[entry]
                if shown != current:
                    run_lengths[run] = length
                    run += 1
                    length = 0
                    current = shown
                length += 1
                if shown:
                    voxel_classes[voxel] = entry
                    if with_normals:
                        voxel_normals[voxel] = _normal_index(volume, x, y, z, scales, spacing, resampled, encoding,
                                                             half_grid, zero_index)
                    voxel += 1
            run_lengths[run] = length
