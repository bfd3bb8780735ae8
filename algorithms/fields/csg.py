"""Constructive solid geometry on signed distance fields (source 002, section 3.3.1): union, intersection and
difference of fields on one grid, their smooth variants, a volume's isosurface as a field, and the result as a
closed, outward triangle mesh by our marching cubes.

Method (source 002, section 3.3.1)
----------------------------------
With fields negative inside, the source combines them voxel by voxel: union ``min(f1, f2)``, intersection
``max(f1, f2)``, difference ``max(f1, -f2)``. Several fields fold from the left (``a - b - c = max(a, -b, -c)``).
The results are not Euclidean distances everywhere (inside a union near where two solids overlap, for example),
but their zero sets are exactly the boolean's boundary and their sign is exact, which is what meshing needs.

Smooth variants (``blend_mm`` > 0) replace ``min`` by the polynomial smooth minimum ``min(a, b) - k h^2 / 4`` with
``h = max(k - |a - b|, 0) / k`` (k the blend radius in mm; Quilez, "smooth minimum", 2013) and ``max(a, b)`` by
``-smin(-a, -b)``: the fields agree with the sharp ones wherever ``|a - b| >= k`` and round the creases within
about ``k / 4`` of them.

The result is meshed in the app layer (:func:`app.operations.distance.mesh_field`, our marching cubes: the
families of ``algorithms`` do not import each other).

A volume (CT, MRI) joins in through its isosurface: ``f = (iso - v) / g``, with ``g`` the median gradient magnitude
(units per mm) at the voxels next to the isosurface, so ``f`` is negative above the isovalue and about mm near it.

Array order: fields are ``(nz, ny, nx)`` float32 mm on one :class:`~algorithms.common.grid.Grid`; meshes are
``(x, y, z)`` LPS mm, triangles counter-clockwise seen from outside.

References
----------
Source 002 (German MSc thesis "Vergleich von Volumenmodellen", see docs/references.md), section 3.3.1
"Konstruktive Festkörpergeometrie".
I. Quilez, "Smooth minimum", 2013 (polynomial smooth min).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numba import njit, prange


__all__ = ["OPERATIONS", "combine", "isosurface_field", "negated_padded"]

OPERATIONS = ("union", "intersection", "difference")


#: Elements per parallel chunk of :func:`_fold`.
CHUNK = 1 << 16


@njit(cache=True, nogil=True, parallel=True)
def _fold(out, first, other, operation, blend, bad):
    """``out = first (op) other`` in one pass (``out`` may be ``first``); ``operation`` 0 union, 1 intersection, 2
    difference; ``blend`` mm. ``bad[c]`` is set where chunk ``c`` met a NaN or infinite input."""
    flat = out.reshape(-1)
    left = first.reshape(-1)
    right = other.reshape(-1)
    n = flat.shape[0]
    for c in prange((n + CHUNK - 1) // CHUNK):
        finite = True
        for q in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            a = left[q]
            b = right[q]
            finite &= (abs(a) < np.inf) & (abs(b) < np.inf)  # False for NaN too
            if operation == 2:
                b = -b
            if operation == 0:  # smooth or sharp minimum
                m = min(a, b)
                if blend > 0.0:
                    h = max(blend - abs(a - b), 0.0) / blend
                    m -= 0.25 * blend * h * h
            else:  # maximum
                m = max(a, b)
                if blend > 0.0:
                    h = max(blend - abs(a - b), 0.0) / blend
                    m += 0.25 * blend * h * h
            flat[q] = m
        if not finite:
            bad[c] = True


def combine(fields: Sequence[np.ndarray], operation: str, *, blend_mm: float = 0.0,
            out: np.ndarray | None = None) -> np.ndarray:
    """``fields[0] (op) fields[1] (op) ...`` (see the module notes) as float32, in one parallel pass per extra field.

    Parameters
    ----------
    fields : sequence of ndarray (nz, ny, nx)
        Two or more signed distance fields (mm, negative inside) on the same grid.
    operation : {"union", "intersection", "difference"}
        ``min``, ``max``, or ``max(f1, -f2, -f3, ...)``.
    blend_mm : float
        Blend radius of the smooth variant (0: sharp).
    out : ndarray (nz, ny, nx) float32, C order, optional
        Where to write the result (a new array when omitted; it may be one of the fields).

    Raises
    ------
    ValueError
        Fewer than two fields, differing shapes, non-finite values, unknown operation, negative blend, bad ``out``.
    """
    if operation not in OPERATIONS:
        raise ValueError(f"operation must be one of {', '.join(OPERATIONS)}, got {operation!r}")
    blend_mm = float(blend_mm)
    if not (blend_mm >= 0 and np.isfinite(blend_mm)):
        raise ValueError(f"the blend radius must be 0 or a positive number of mm, got {blend_mm}")
    if len(fields) < 2:
        raise ValueError(f"CSG combines two or more fields, got {len(fields)}")
    shape = np.shape(fields[0])
    if len(shape) != 3:
        raise ValueError(f"fields must be 3-D arrays (nz, ny, nx), got shape {shape}")
    for n, f in enumerate(fields[1:], start=2):
        if np.shape(f) != shape:
            raise ValueError(f"field {n} has shape {np.shape(f)}, field 1 {shape}: resample them onto one grid first")
    if out is None:
        out = np.empty(shape, dtype=np.float32)
    elif out.shape != shape or out.dtype != np.float32 or not out.flags.c_contiguous or not out.flags.writeable:
        raise ValueError(f"out must be a writeable C-ordered float32 array of shape {shape}")
    code = OPERATIONS.index(operation)
    bad = np.zeros((int(np.prod(shape)) + CHUNK - 1) // CHUNK, dtype=np.bool_)
    first = np.ascontiguousarray(fields[0], dtype=np.float32)
    for f in fields[1:]:
        _fold(out, first, np.ascontiguousarray(f, dtype=np.float32), code, np.float32(blend_mm), bad)
        first = out
    if bad.any():
        for n, f in enumerate(fields, start=1):
            if not np.all(np.isfinite(f)):
                raise ValueError(f"field {n} holds NaN or infinite values; CSG needs finite distances (clamp or "
                                 "propagate them)")
    return out


@njit(cache=True, nogil=True, parallel=True)
def _negate_into(out, values, slice_max):
    """``out[1:-1, 1:-1, 1:-1] = -values`` and each slice's largest value into ``slice_max``, in one pass."""
    nz, ny, nx = values.shape
    for k in prange(nz):
        top = -np.inf
        for j in range(ny):
            for i in range(nx):
                v = values[k, j, i]
                out[k + 1, j + 1, i + 1] = -v
                if v > top:
                    top = v
        slice_max[k] = top


def negated_padded(values: np.ndarray, level: float = 0.0) -> np.ndarray:
    """``-values`` in float32, padded by one sample on every side with ``-(max(values.max(), level) + 1)``: a
    field (negative inside) turned into what marching cubes meshes at ``-level`` (inside at values >= the level,
    triangles facing away from it), closed at the grid's border by the padding. One pass over the field (the
    negation, the copy into the padded array and the maximum together) instead of three."""
    values = np.ascontiguousarray(values, dtype=np.float32)
    if values.ndim != 3 or 0 in values.shape:
        raise ValueError(f"a field must be a non-empty 3-D array (nz, ny, nx), got shape {values.shape}")
    nz, ny, nx = values.shape
    out = np.empty((nz + 2, ny + 2, nx + 2), dtype=np.float32)
    slice_max = np.empty(nz, dtype=np.float32)
    _negate_into(out, values, slice_max)
    top = float(slice_max.max())  # NaN samples are skipped here; marching cubes refuses them inside the field
    outside = np.float32(-(max(top, float(level)) + 1.0))
    out[0], out[-1] = outside, outside
    out[:, 0], out[:, -1] = outside, outside
    out[:, :, 0], out[:, :, -1] = outside, outside
    return out


def isosurface_field(values: np.ndarray, iso: float, *, spacing=(1.0, 1.0, 1.0)) -> np.ndarray:
    """A volume's isosurface as a field: ``(iso - v) / g`` float32, negative where ``v > iso`` (see the module
    notes; ``spacing`` ``(sx, sy, sz)`` mm). ValueError when the isovalue is outside the values."""
    values = np.asarray(values)
    if values.ndim != 3:
        raise ValueError(f"the volume must be a 3-D array (nz, ny, nx), got shape {values.shape}")
    iso = float(iso)
    low, high = float(values.min()), float(values.max())
    if not low < iso < high:
        raise ValueError(f"the isovalue {iso:g} is not inside the volume's values ({low:g} to {high:g}), so it has "
                         "no surface")
    v = values.astype(np.float32)
    above = v > iso
    near = np.zeros_like(above)
    for axis in range(3):  # voxels with a neighbour on the other side of the isovalue
        change = np.diff(above, axis=axis)
        lead = [slice(None)] * 3
        lead[axis] = slice(0, -1)
        trail = [slice(None)] * 3
        trail[axis] = slice(1, None)
        near[tuple(lead)] |= change
        near[tuple(trail)] |= change
    sx, sy, sz = (float(s) for s in spacing)
    gz, gy, gx = np.gradient(v, sz, sy, sx)
    magnitude = np.sqrt(gx[near] ** 2 + gy[near] ** 2 + gz[near] ** 2)
    scale = float(np.median(magnitude)) if magnitude.size else 0.0
    if not scale > 0:
        raise ValueError("the volume has no gradient at its isosurface, so it cannot be scaled to mm")
    return ((np.float32(iso) - v) / np.float32(scale)).astype(np.float32)
