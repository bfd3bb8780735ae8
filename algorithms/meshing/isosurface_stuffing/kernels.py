"""numba kernels of isosurface stuffing (see :mod:`.core` for the method and :mod:`.lattice` for the data layout).

Every kernel runs in parallel over lattice layers (``prange`` over ``k``) or over the records of the points near the
surface; counts per layer and prefix sums (in :mod:`.core`) give each layer its first output index, so the output
is the same whatever the number of threads.

Lattice layout (h = lattice spacing, all indices ``[k, j, i]``):

- outer grid ``O(i, j, k)`` at ``origin + h (i, j, k)``, arrays of shape ``(NZ + 1, NY + 1, NX + 1)``;
- inner grid ``I(i, j, k)`` at ``origin + h (i + 1/2, j + 1/2, k + 1/2)``, arrays of shape ``(NZ, NY, NX)``;
- every point owns seven half-edges (source 002): directions 0-2 are its black edges to ``+x, +y, +z``, directions
  3-6 red edges to the four points of the other grid just above it: ``O(i, j, k)`` to ``I(i - 1 + a, j - 1 + b, k)``
  and ``I(i, j, k)`` to ``O(i + a, j + b, k + 1)``, with direction ``3 + a + 2 b``. A cut parameter ``t`` runs from the owner (0) to the other end (1).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# ---------------------------------------------------------------------------------------------------------------
# The field
# ---------------------------------------------------------------------------------------------------------------


@njit(cache=True, nogil=True, inline="always")
def _sample(volume, i, j, k, pad):
    nz, ny, nx = volume.shape
    if i < 0 or j < 0 or k < 0 or i >= nx or j >= ny or k >= nz:
        return pad
    return np.float64(volume[k, j, i])


@njit(cache=True, nogil=True)
def field_at(volume, x, y, z, geometry):
    """``direction * (value - iso)`` of the trilinear interpolant at ``(x, y, z)`` mm (volume frame).

    ``geometry``: ``(ox, oy, oz, sx, sy, sz, iso, pad, direction)``; samples outside the volume take ``pad``.
    """
    u = (x - geometry[0]) / geometry[3]
    v = (y - geometry[1]) / geometry[4]
    w = (z - geometry[2]) / geometry[5]
    i0 = int(np.floor(u))
    j0 = int(np.floor(v))
    k0 = int(np.floor(w))
    fu = u - i0
    fv = v - j0
    fw = w - k0
    pad = geometry[7]
    c00 = _sample(volume, i0, j0, k0, pad) * (1.0 - fu) + _sample(volume, i0 + 1, j0, k0, pad) * fu
    c10 = _sample(volume, i0, j0 + 1, k0, pad) * (1.0 - fu) + _sample(volume, i0 + 1, j0 + 1, k0, pad) * fu
    c01 = _sample(volume, i0, j0, k0 + 1, pad) * (1.0 - fu) + _sample(volume, i0 + 1, j0, k0 + 1, pad) * fu
    c11 = _sample(volume, i0, j0 + 1, k0 + 1, pad) * (1.0 - fu) + _sample(volume, i0 + 1, j0 + 1, k0 + 1, pad) * fu
    c0 = c00 * (1.0 - fv) + c10 * fv
    c1 = c01 * (1.0 - fv) + c11 * fv
    return geometry[8] * ((c0 * (1.0 - fw) + c1 * fw) - geometry[6])


@njit(cache=True, nogil=True, forceinline=True)
def _sign(value):
    if value > 0.0:
        return 1
    if value < 0.0:
        return -1
    return 0


#: Voxels per side of the blocks whose value range lets :func:`classify` skip the interpolation.
BLOCK = 4


@njit(cache=True, nogil=True, parallel=True)
def block_ranges(volume, lows, highs):
    """Lowest and highest sample of every ``BLOCK``-voxel block and the samples one past it (the samples the
    trilinear interpolant of a point in the block reads)."""
    nz, ny, nx = volume.shape
    bz, by, bx = lows.shape
    for c in prange(bz):
        for b in range(by):
            for a in range(bx):
                low = np.inf
                high = -np.inf
                for k in range(c * BLOCK, min((c + 1) * BLOCK + 1, nz)):
                    for j in range(b * BLOCK, min((b + 1) * BLOCK + 1, ny)):
                        for i in range(a * BLOCK, min((a + 1) * BLOCK + 1, nx)):
                            v = np.float64(volume[k, j, i])
                            low = min(low, v)
                            high = max(high, v)
                lows[c, b, a] = low
                highs[c, b, a] = high


@njit(cache=True, nogil=True)
def _classify_point(volume, x, y, z, geometry, lows, highs):
    nz, ny, nx = volume.shape
    u = (x - geometry[0]) / geometry[3]
    v = (y - geometry[1]) / geometry[4]
    w = (z - geometry[2]) / geometry[5]
    if 0.0 <= u < nx - 1 and 0.0 <= v < ny - 1 and 0.0 <= w < nz - 1:
        a = int(u) // BLOCK
        b = int(v) // BLOCK
        c = int(w) // BLOCK
        iso = geometry[6]
        if highs[c, b, a] < iso:
            return -1 if geometry[8] > 0 else 1
        if lows[c, b, a] > iso:
            return 1 if geometry[8] > 0 else -1
    return _sign(field_at(volume, x, y, z, geometry))


@njit(cache=True, nogil=True, parallel=True)
def classify(volume, geometry, lattice, lows, highs, sign_o, sign_i, row_o, row_i):
    """Sign of the field at every lattice point (skipping the interpolation in blocks entirely on one side);
    ``row_o[k, j]``/``row_i[k, j]`` = 1 where a row has a positive point. ``lattice``: ``(x0, y0, z0, h)``."""
    nzo, nyo, nxo = sign_o.shape
    nzi, nyi, nxi = sign_i.shape
    x0, y0, z0, h = lattice[0], lattice[1], lattice[2], lattice[3]
    for k in prange(nzo):
        for j in range(nyo):
            any_pos = 0
            for i in range(nxo):
                s = _classify_point(volume, x0 + h * i, y0 + h * j, z0 + h * k, geometry, lows, highs)
                sign_o[k, j, i] = s
                if s > 0:
                    any_pos = 1
            row_o[k, j] = any_pos
        if k < nzi:
            for j in range(nyi):
                any_pos = 0
                for i in range(nxi):
                    s = _classify_point(volume, x0 + h * (i + 0.5), y0 + h * (j + 0.5), z0 + h * (k + 0.5),
                                        geometry, lows, highs)
                    sign_i[k, j, i] = s
                    if s > 0:
                        any_pos = 1
                row_i[k, j] = any_pos


# ---------------------------------------------------------------------------------------------------------------
# Neighbours: the 14 edges of a point. Grid 0 = outer, 1 = inner. Each edge is returned as the other end and the
# owner of the half-edge with its direction, and whether the point itself is the owner.
# ---------------------------------------------------------------------------------------------------------------


@njit(cache=True, nogil=True)
def neighbour(grid, i, j, k, e):
    """Edge ``e`` (0-13) of a point: ``(other_grid, oi, oj, ok, owner_grid, wi, wj, wk, direction, black)``.

    Edges 0-5 are black (``+x, -x, +y, -y, +z, -z``), 6-13 red (``a = e & 1, b = e >> 1 & 1, c = e >> 2 & 1`` of
    ``e - 6``). Indices may fall outside the arrays (the caller checks).
    """
    if e < 6:
        axis = e // 2
        step = 1 if e % 2 == 0 else -1
        di = step if axis == 0 else 0
        dj = step if axis == 1 else 0
        dk = step if axis == 2 else 0
        if step > 0:
            return grid, i + di, j + dj, k + dk, grid, i, j, k, axis, True
        return grid, i + di, j + dj, k + dk, grid, i + di, j + dj, k + dk, axis, True
    r = e - 6
    a = r & 1
    b = (r >> 1) & 1
    c = (r >> 2) & 1
    if grid == 0:
        oi, oj, ok = i - 1 + a, j - 1 + b, k - 1 + c
        if c == 1:  # inner point above: owned by this outer point
            return 1, oi, oj, ok, 0, i, j, k, 3 + a + 2 * b, False
        return 1, oi, oj, ok, 1, oi, oj, ok, 3 + (1 - a) + 2 * (1 - b), False
    oi, oj, ok = i + a, j + b, k + c
    if c == 1:  # outer point above: owned by this inner point
        return 0, oi, oj, ok, 1, i, j, k, 3 + a + 2 * b, False
    return 0, oi, oj, ok, 0, oi, oj, ok, 3 + (1 - a) + 2 * (1 - b), False


@njit(cache=True, nogil=True, inline="always")
def _inside(grid, i, j, k, sign_o, sign_i):
    if grid == 0:
        nz, ny, nx = sign_o.shape
    else:
        nz, ny, nx = sign_i.shape
    return 0 <= i < nx and 0 <= j < ny and 0 <= k < nz


@njit(cache=True, nogil=True, inline="always")
def _get(grid, i, j, k, a_o, a_i):
    if grid == 0:
        return a_o[k, j, i]
    return a_i[k, j, i]


@njit(cache=True, nogil=True, inline="always")
def position(grid, i, j, k, lattice):
    half = 0.5 * grid
    h = lattice[3]
    return lattice[0] + h * (i + half), lattice[1] + h * (j + half), lattice[2] + h * (k + half)


@njit(cache=True, nogil=True, inline="always")
def _flag_if_cut(s, og, oi, oj, ok, sign_o, sign_i, near_o, near_i):
    """Mark the other end of an owned half-edge and say whether the edge is cut (opposite nonzero signs)."""
    if og == 0:
        if s * sign_o[ok, oj, oi] < 0:
            near_o[ok, oj, oi] = 1
            return True
    else:
        if s * sign_i[ok, oj, oi] < 0:
            near_i[ok, oj, oi] = 1
            return True
    return False


@njit(cache=True, nogil=True, parallel=True)
def mark_near(sign_o, sign_i, row_o, row_i, near_o, near_i):
    """Flag every point incident to a cut edge (opposite nonzero signs), by visiting each point's seven owned
    half-edges. Two threads may flag the same point; both write 1."""
    nzo, nyo, nxo = sign_o.shape
    nzi, nyi, nxi = sign_i.shape
    for k in prange(nzo):
        for j in range(nyo):
            if not _row_near_positive(0, j, k, row_o, row_i):
                continue
            for i in range(nxo):
                s = sign_o[k, j, i]
                if s == 0:
                    continue
                hit = False
                if i + 1 < nxo:
                    hit |= _flag_if_cut(s, 0, i + 1, j, k, sign_o, sign_i, near_o, near_i)
                if j + 1 < nyo:
                    hit |= _flag_if_cut(s, 0, i, j + 1, k, sign_o, sign_i, near_o, near_i)
                if k + 1 < nzo:
                    hit |= _flag_if_cut(s, 0, i, j, k + 1, sign_o, sign_i, near_o, near_i)
                if k < nzi:
                    for b in range(2):
                        for a in range(2):
                            ii = i - 1 + a
                            jj = j - 1 + b
                            if 0 <= ii < nxi and 0 <= jj < nyi:
                                hit |= _flag_if_cut(s, 1, ii, jj, k, sign_o, sign_i, near_o, near_i)
                if hit:
                    near_o[k, j, i] = 1
        if k < nzi:
            for j in range(nyi):
                if not _row_near_positive(1, j, k, row_o, row_i):
                    continue
                for i in range(nxi):
                    s = sign_i[k, j, i]
                    if s == 0:
                        continue
                    hit = False
                    if i + 1 < nxi:
                        hit |= _flag_if_cut(s, 1, i + 1, j, k, sign_o, sign_i, near_o, near_i)
                    if j + 1 < nyi:
                        hit |= _flag_if_cut(s, 1, i, j + 1, k, sign_o, sign_i, near_o, near_i)
                    if k + 1 < nzi:
                        hit |= _flag_if_cut(s, 1, i, j, k + 1, sign_o, sign_i, near_o, near_i)
                    for b in range(2):
                        for a in range(2):
                            hit |= _flag_if_cut(s, 0, i + a, j + b, k + 1, sign_o, sign_i, near_o, near_i)
                    if hit:
                        near_i[k, j, i] = 1


@njit(cache=True, nogil=True, inline="always")
def _row_near_positive(grid, j, k, row_o, row_i):
    """Whether any point within one edge of row ``(j, k)`` of ``grid`` can be positive."""
    nzo, nyo = row_o.shape
    nzi, nyi = row_i.shape
    same = row_o if grid == 0 else row_i
    nz, ny = same.shape
    for dk in range(-1, 2):
        for dj in range(-1, 2):
            if (dk == 0 or dj == 0) and 0 <= k + dk < nz and 0 <= j + dj < ny and same[k + dk, j + dj]:
                return True
    if grid == 0:
        for dk in range(-1, 1):
            for dj in range(-1, 1):
                if 0 <= k + dk < nzi and 0 <= j + dj < nyi and row_i[k + dk, j + dj]:
                    return True
    else:
        for dk in range(0, 2):
            for dj in range(0, 2):
                if 0 <= k + dk < nzo and 0 <= j + dj < nyo and row_o[k + dk, j + dj]:
                    return True
    return False


@njit(cache=True, nogil=True)
def zero_vertices(sign_o, sign_i, zeros, grids, keep):
    """Which zero points (``(k, j, i)`` rows of ``zeros`` on grid ``grids``) have a positive neighbour."""
    for n in range(zeros.shape[0]):
        grid = grids[n]
        k, j, i = zeros[n, 0], zeros[n, 1], zeros[n, 2]
        for e in range(14):
            og, oi, oj, ok, _, _, _, _, _, _ = neighbour(grid, i, j, k, e)
            if _inside(og, oi, oj, ok, sign_o, sign_i) and _get(og, oi, oj, ok, sign_o, sign_i) > 0:
                keep[n] = 1
                break


# Owned half-edge d of a point -> the other end (direction 0-2 black +axis, 3-6 red), as an edge number of
# ``neighbour``: black +x, +y, +z are edges 0, 2, 4; red direction 3 + a + 2b is edge 6 + a + 2b + 4 (the point of
# the other grid above).
@njit(cache=True, nogil=True, forceinline=True)
def owned_edge(grid, d):
    if d < 3:
        return 2 * d
    return 6 + (d - 3) + 4


@njit(cache=True, nogil=True, parallel=True)
def compute_cuts(volume, geometry, lattice, sign_o, sign_i, rec_point, rec_t, steps, linear):
    """Cut parameter of every owned half-edge with opposite end signs, by bisection on the field (``steps``
    halvings) or, with ``linear``, by linear interpolation of the end values."""
    for r in prange(rec_point.shape[0]):
        grid, i, j, k = (np.int64(rec_point[r, 0]), np.int64(rec_point[r, 1]), np.int64(rec_point[r, 2]),
                         np.int64(rec_point[r, 3]))  # int64, as zero_vertices passes them to neighbour
        s = _get(grid, i, j, k, sign_o, sign_i)
        px, py, pz = position(grid, i, j, k, lattice)
        for d in range(7):
            og, oi, oj, ok, _, _, _, _, _, _ = neighbour(grid, i, j, k, owned_edge(grid, d))
            if not _inside(og, oi, oj, ok, sign_o, sign_i) or _get(og, oi, oj, ok, sign_o, sign_i) * s >= 0:
                continue
            qx, qy, qz = position(og, oi, oj, ok, lattice)
            if linear:
                fp = field_at(volume, px, py, pz, geometry)
                fq = field_at(volume, qx, qy, qz, geometry)
                t = fp / (fp - fq)
            else:
                lo = 0.0
                hi = 1.0
                f_lo = field_at(volume, px, py, pz, geometry)
                f_hi = field_at(volume, qx, qy, qz, geometry)
                for _ in range(steps):
                    mid = 0.5 * (lo + hi)
                    f = field_at(volume, px + mid * (qx - px), py + mid * (qy - py), pz + mid * (qz - pz), geometry)
                    if f == 0.0:
                        lo = mid
                        hi = mid
                        break
                    if (f > 0.0) == (f_lo > 0.0):
                        lo = mid
                        f_lo = f
                    else:
                        hi = mid
                        f_hi = f
                # the zero of the line through the bracket's ends (the interpolant is nearly linear there)
                t = lo if hi == lo else lo + (hi - lo) * f_lo / (f_lo - f_hi)
            rec_t[r, d] = min(max(t, 1e-6), 1.0 - 1e-6)


@njit(cache=True, nogil=True, parallel=True)
def warp(sign_o, sign_i, ref_o, ref_i, rec_point, rec_t, rec_pos, lattice, alpha_long, alpha_short, phase,
         warped):
    """Warp the violated points of one sign (``phase`` +1, then -1): a point with a cut point on one of its 14
    edges closer than alpha times the edge's length moves to the closest such cut point and becomes zero. In the
    second phase only cut points whose other end is still positive count (the first phase's warps removed the
    others)."""
    h = lattice[3]
    black_length = h
    red_length = h * np.sqrt(3.0) / 2.0
    for r in prange(rec_point.shape[0]):
        grid, i, j, k = (np.int64(rec_point[r, 0]), np.int64(rec_point[r, 1]), np.int64(rec_point[r, 2]),
                         np.int64(rec_point[r, 3]))  # int64, as zero_vertices passes them to neighbour
        if _get(grid, i, j, k, sign_o, sign_i) != phase:
            continue
        best = 1e300
        bx = by = bz = 0.0
        px, py, pz = position(grid, i, j, k, lattice)
        for e in range(14):
            og, oi, oj, ok, wg, wi, wj, wk, d, black = neighbour(grid, i, j, k, e)
            if not _inside(og, oi, oj, ok, sign_o, sign_i) or _get(og, oi, oj, ok, sign_o, sign_i) != -phase:
                continue
            owner = _get(wg, wi, wj, wk, ref_o, ref_i)
            t = rec_t[owner, d]
            if t < 0.0:
                continue
            t_here = t if (wg == grid and wi == i and wj == j and wk == k) else 1.0 - t
            alpha = alpha_long if black else alpha_short
            if t_here < alpha:
                distance = t_here * (black_length if black else red_length)
                if distance < best:
                    best = distance
                    qx, qy, qz = position(og, oi, oj, ok, lattice)
                    bx = px + t_here * (qx - px)
                    by = py + t_here * (qy - py)
                    bz = pz + t_here * (qz - pz)
        if best < 1e300:
            rec_pos[r, 0] = bx
            rec_pos[r, 1] = by
            rec_pos[r, 2] = bz
            warped[r] = 1
            if grid == 0:
                sign_o[k, j, i] = 0
            else:
                sign_i[k, j, i] = 0


@njit(cache=True, nogil=True, parallel=True)
def number_cuts(sign_o, sign_i, rec_point, rec_t, first, rec_cut, lattice, points, counting, counts):
    """Ids (from ``first[r]``) and positions of the cut points that survive the warp (both ends still of opposite
    nonzero signs). With ``counting`` only ``counts[r]`` is filled."""
    for r in prange(rec_point.shape[0]):
        grid, i, j, k = (np.int64(rec_point[r, 0]), np.int64(rec_point[r, 1]), np.int64(rec_point[r, 2]),
                         np.int64(rec_point[r, 3]))  # int64, as zero_vertices passes them to neighbour
        s = _get(grid, i, j, k, sign_o, sign_i)
        n = 0 if counting else first[r]
        for d in range(7):
            t = rec_t[r, d]
            if t < 0.0 or s == 0:
                continue
            og, oi, oj, ok, _, _, _, _, _, _ = neighbour(grid, i, j, k, owned_edge(grid, d))
            if _get(og, oi, oj, ok, sign_o, sign_i) * s >= 0:
                continue
            if not counting:
                rec_cut[r, d] = n
                px, py, pz = position(grid, i, j, k, lattice)
                qx, qy, qz = position(og, oi, oj, ok, lattice)
                points[n, 0] = px + t * (qx - px)
                points[n, 1] = py + t * (qy - py)
                points[n, 2] = pz + t * (qz - pz)
            n += 1
        if counting:
            counts[r] = n
