"""numba kernels of mesh voxelisation (see :mod:`.voxelise` for the method and its conventions).

Everything happens in the grid's index frame: point ``(x, y, z)`` here is the continuous index ``(i, j, k)``, the
voxel centres are the integer points, and a *row* is the line ``y = j, z = k`` along x.

1. :func:`triangle_rows`: per triangle, the rows its (y, z) bounding box can meet, clipped to the grid
   (parallel over triangles).
2. :func:`slice_buckets`: the triangles of each slice ``k`` as CSR lists (two passes: count, then fill).
3. :func:`fill_slices`: parallel over slices; each slice tests its triangles against the rows they may meet
   (exact orientation signs with simulation of simplicity, :mod:`.predicates`), collects the crossings
   ``(row, x, direction)``, sorts them by row with a counting sort and along each row by x, and fills the row:
   by parity, or with the running sum of signed crossings (the integer winding number of a closed chain).

A voxel ``i`` counts a crossing at ``x`` when ``x <= i``: the voxel centre is taken as moved by an infinitesimal
``+e'`` along x, much larger than the row's ``(e, e^2)`` in (y, z). With the row perturbation this is a single
symbolic perturbation of every voxel centre, so a centre lying exactly on the surface is decided once and
consistently.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .predicates import edge_side


#: Index coordinates are rounded to multiples of 2^-30 voxel (see :func:`index_points`).
SNAP = 2.0 ** 30


@njit(cache=True, nogil=True, parallel=True)
def index_points(points, origin, matrix, out):
    """``out = (points - origin) @ matrix`` (world mm to continuous index), rounded to multiples of 2^-30 voxel.

    ``matrix`` is ``direction / spacing`` (columns scaled). Rounding to that fine lattice moves no vertex by more
    than 1e-9 voxel, but a vertex meant to lie on a voxel centre or a voxel boundary lands there exactly even after
    a rotation, so meshes made on the grid are voxelised exactly.
    """
    for p in prange(points.shape[0]):
        x = points[p, 0] - origin[0]
        y = points[p, 1] - origin[1]
        z = points[p, 2] - origin[2]
        for axis in range(3):
            value = x * matrix[0, axis] + y * matrix[1, axis] + z * matrix[2, axis]
            out[p, axis] = np.rint(value * SNAP) / SNAP


@njit(cache=True, nogil=True, parallel=True)
def triangle_rows(points, triangles, ny, nz, rows):
    """``rows[t] = (j_low, j_high, k_low, k_high)``, the inclusive ranges of rows the bounding box of triangle
    ``t`` in (y, z) covers, clipped to the grid; ``j_low > j_high`` or ``k_low > k_high`` when it meets none."""
    for t in prange(triangles.shape[0]):
        y_low = math.inf
        y_high = -math.inf
        z_low = math.inf
        z_high = -math.inf
        for c in range(3):
            p = triangles[t, c]
            y = points[p, 1]
            z = points[p, 2]
            y_low = min(y_low, y)
            y_high = max(y_high, y)
            z_low = min(z_low, z)
            z_high = max(z_high, z)
        rows[t, 0] = max(int(math.ceil(max(y_low, -1.0))), 0)
        rows[t, 1] = min(int(math.floor(min(y_high, float(ny)))), ny - 1)
        rows[t, 2] = max(int(math.ceil(max(z_low, -1.0))), 0)
        rows[t, 3] = min(int(math.floor(min(z_high, float(nz)))), nz - 1)


@njit(cache=True, nogil=True)
def slice_buckets(rows, nz):
    """CSR lists of the triangles whose rows meet each slice: ``offsets`` (nz + 1) and ``members``."""
    counts = np.zeros(nz + 1, dtype=np.int64)
    for t in range(rows.shape[0]):
        if rows[t, 0] > rows[t, 1]:
            continue
        for k in range(rows[t, 2], rows[t, 3] + 1):
            counts[k + 1] += 1
    for k in range(nz):
        counts[k + 1] += counts[k]
    members = np.empty(counts[nz], dtype=np.int32)
    cursor = counts[:nz].copy()
    for t in range(rows.shape[0]):
        if rows[t, 0] > rows[t, 1]:
            continue
        for k in range(rows[t, 2], rows[t, 3] + 1):
            members[cursor[k]] = t
            cursor[k] += 1
    return counts, members


@njit(cache=True, nogil=True, inline="always")
def _row_crossing(points, a, b, c, y, z):
    """Whether the perturbed row point ``(y, z)`` lies inside the (y, z) projection of triangle ``(a, b, c)``, the
    crossing's direction (-1: the triangle faces +x, the row leaves the solid; +1 it enters) and its x.

    Each edge is judged from its lower to its higher vertex index, so every triangle sharing it sees the same
    answer: a row through an edge or a vertex crosses exactly one triangle of each sheet of surface there.
    """
    ay, az = points[a, 1], points[a, 2]
    by, bz = points[b, 1], points[b, 2]
    cy, cz = points[c, 1], points[c, 2]
    # edge a -> b: weight of c
    if a < b:
        s_ab, w_c = edge_side(ay, az, by, bz, y, z)
    else:
        s_ab, w_c = edge_side(by, bz, ay, az, y, z)
        s_ab, w_c = -s_ab, -w_c
    if s_ab == 0:
        return 0, 0.0
    if b < c:
        s_bc, w_a = edge_side(by, bz, cy, cz, y, z)
    else:
        s_bc, w_a = edge_side(cy, cz, by, bz, y, z)
        s_bc, w_a = -s_bc, -w_a
    if s_bc != s_ab:
        return 0, 0.0
    if c < a:
        s_ca, w_b = edge_side(cy, cz, ay, az, y, z)
    else:
        s_ca, w_b = edge_side(ay, az, cy, cz, y, z)
        s_ca, w_b = -s_ca, -w_b
    if s_ca != s_ab:
        return 0, 0.0
    # Barycentric weights (signed areas opposite each corner) give x as a convex combination of the corners', so
    # x stays within the triangle even for slivers; weights of the wrong sign (rounding) count as zero.
    w_a = max(w_a * s_ab, 0.0)
    w_b = max(w_b * s_ab, 0.0)
    w_c = max(w_c * s_ab, 0.0)
    total = w_a + w_b + w_c
    ax, bx, cx = points[a, 0], points[b, 0], points[c, 0]
    if total > 0.0:
        x = (w_a * ax + w_b * bx + w_c * cx) / total
        x = min(max(x, min(ax, min(bx, cx))), max(ax, max(bx, cx)))
    else:
        x = (ax + bx + cx) / 3.0
    return -s_ab, x


@njit(cache=True, nogil=True)
def _sort_row(xs, signs, start, stop):
    """Insertion sort of ``xs[start:stop]`` (with ``signs``), ascending; rows hold few crossings."""
    for m in range(start + 1, stop):
        x = xs[m]
        s = signs[m]
        n = m - 1
        while n >= start and xs[n] > x:
            xs[n + 1] = xs[n]
            signs[n + 1] = signs[n]
            n -= 1
        xs[n + 1] = x
        signs[n + 1] = s


@njit(cache=True, nogil=True, forceinline=True)
def _first_voxel(x, nx):
    """The first voxel ``i`` (clipped to ``0..nx``) at or after the crossing ``x``: the voxels that count it."""
    if x <= 0.0:
        return 0
    if x >= nx:
        return nx
    return int(math.ceil(x))


@njit(cache=True, nogil=True)
def _fill_row(row, xs, signs, start, stop, winding):
    """Fill one row from its sorted crossings.

    Parity (``winding`` false): 1 where the number of crossings at or before the voxel is odd. Winding: the
    running sum of crossing directions (the winding number of a closed chain), clamped to the int8 range, wherever
    it is not 0. ``row`` is int8 under both rules.
    """
    nx = row.shape[0]
    level = 0
    for m in range(start, stop):
        level = level + signs[m] if winding else level ^ 1
        if level == 0:
            continue
        first = _first_voxel(xs[m], nx)
        last = _first_voxel(xs[m + 1], nx) if m + 1 < stop else nx  # an unbalanced row runs to the grid's end
        if last > first:
            row[first:last] = min(max(level, -128), 127) if winding else 1


@njit(cache=True, nogil=True, parallel=True)
def fill_slices(points, triangles, rows, offsets, members, slices, out, winding, direction_sign):
    """Voxelise the slices ``slices`` (k indices) of ``out`` (``(nz, ny, nx)``, zero on entry).

    ``out`` is int8 (callers pass an int8 view of a uint8 mask under both rules, so this is compiled once). Parity:
    ``out`` becomes 1 inside. ``winding``: ``out`` receives the winding number of the closed chain (the running sum
    of crossing directions) wherever it is not 0;
    ``direction_sign`` is -1 when the index frame is left-handed (it reverses every triangle's facing there).
    Returns the number of crossings found per slice of ``slices``.
    """
    ny = out.shape[1]
    found = np.zeros(slices.shape[0], dtype=np.int64)
    for q in prange(slices.shape[0]):
        k = slices[q]
        first, last = offsets[k], offsets[k + 1]
        if first == last:
            continue
        capacity = 0
        for m in range(first, last):
            t = members[m]
            capacity += rows[t, 1] - rows[t, 0] + 1
        row_of = np.empty(capacity, dtype=np.int32)
        x_of = np.empty(capacity, dtype=np.float64)
        sign_of = np.empty(capacity, dtype=np.int8)
        count = 0
        z = float(k)
        for m in range(first, last):
            t = members[m]
            a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            for j in range(rows[t, 0], rows[t, 1] + 1):
                direction, x = _row_crossing(points, a, b, c, float(j), z)
                if direction != 0:
                    row_of[count] = j
                    x_of[count] = x
                    sign_of[count] = direction * direction_sign
                    count += 1
        found[q] = count
        if count == 0:
            continue
        # counting sort by row
        starts = np.zeros(ny + 1, dtype=np.int64)
        for n in range(count):
            starts[row_of[n] + 1] += 1
        for j in range(ny):
            starts[j + 1] += starts[j]
        cursor = starts[:ny].copy()
        xs = np.empty(count, dtype=np.float64)
        signs = np.empty(count, dtype=np.int8)
        for n in range(count):
            j = row_of[n]
            xs[cursor[j]] = x_of[n]
            signs[cursor[j]] = sign_of[n]
            cursor[j] += 1
        for j in range(ny):
            if starts[j + 1] > starts[j]:
                _sort_row(xs, signs, starts[j], starts[j + 1])
                _fill_row(out[k, j], xs, signs, starts[j], starts[j + 1], winding)
    return found
