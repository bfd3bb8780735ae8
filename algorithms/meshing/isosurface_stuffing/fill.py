"""numba kernels that fill the BCC tetrahedra with the stencils (see :mod:`.stencils` for the table and the parity
rule, :mod:`.kernels` for the lattice layout).

Every BCC tetrahedron is visited once, from the outer black edge it contains: the edge ``O(i, j, k) -> O + e_a``
and the four inner points around it, taken in counter-clockwise order about ``+a``; consecutive pairs give four
tetrahedra ``(A, B, C, D)`` with positive volume, ``A B`` black on the outer grid, ``C D`` black on the inner grid.
Twelve tetrahedra per outer point, as the BCC lattice has twelve per cube.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .kernels import _get

#: Inner-point offsets ``(d_b, d_c)`` of the ring about an outer black edge (b, c: the other axes, right-handed).
RING = np.array([(-1, -1), (0, -1), (0, 0), (-1, 0)], dtype=np.int64)
#: Outward faces of a positive tetrahedron ``(0, 1, 2, 3)``.
OUTWARD_FACES = np.array([(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)], dtype=np.int64)


@njit(cache=True, nogil=True, forceinline=True)
def _sign_code(s):
    if s > 0:
        return 1
    if s < 0:
        return 2
    return 0


@njit(cache=True, nogil=True)
def _vertices(i, j, k, axis, q, ring, slots):
    """Fill ``slots`` (4, 4) with ``(grid, i, j, k)`` of the tetrahedron ``q`` about the outer black edge along
    ``axis`` at ``O(i, j, k)``."""
    b = (axis + 1) % 3
    c = (axis + 2) % 3
    for s in range(4):
        slots[s, 0] = 0 if s < 2 else 1
        slots[s, 1] = i
        slots[s, 2] = j
        slots[s, 3] = k
    slots[1, 1 + axis] += 1
    for s in range(2):
        r = (q + s) % 4
        slots[2 + s, 1 + b] += ring[r, 0]
        slots[2 + s, 1 + c] += ring[r, 1]


@njit(cache=True, nogil=True)
def _in_range(slots, shape_o, shape_i):
    for s in range(4):
        shape = shape_o if slots[s, 0] == 0 else shape_i
        if not (0 <= slots[s, 1] < shape[2] and 0 <= slots[s, 2] < shape[1] and 0 <= slots[s, 3] < shape[0]):
            return False
    return True


@njit(cache=True, nogil=True)
def _parity_bit(slots, p1, p2, m):
    """0 when the parity rule takes the diagonal from ``p1``, 1 from ``p2`` (doubled lattice coordinates)."""
    axis = 0
    for n in range(3):
        if slots[p1, 1 + n] != slots[p2, 1 + n]:
            axis = n
    sigma = 1
    for n in range(3):
        x1 = 2 * slots[p1, 1 + n] + slots[p1, 0]
        other = 2 * slots[p2, 1 + n] + slots[p2, 0] if n == axis else 2 * slots[m, 1 + n] + slots[m, 0]
        if other < x1:
            sigma = -sigma
    from_p1 = sigma == -1 if slots[p1, 0] == 0 else sigma == 1
    return 0 if from_p1 else 1


@njit(cache=True, nogil=True)
def _cut_owner(slots, u, v, out):
    """Owner ``(grid, i, j, k)`` and direction of the half-edge between slots ``u < v``; into ``out`` (5,)."""
    if slots[u, 0] == slots[v, 0]:  # black: the lower end owns it
        lo = u
        axis = 0
        for n in range(3):
            if slots[u, 1 + n] != slots[v, 1 + n]:
                axis = n
                if slots[v, 1 + n] < slots[u, 1 + n]:
                    lo = v
        for n in range(4):
            out[n] = slots[lo, n]
        out[4] = axis
        return
    o = u if slots[u, 0] == 0 else v
    w = v if o == u else u
    if slots[w, 3] == slots[o, 3]:  # inner point above the outer one: the outer owns it
        for n in range(4):
            out[n] = slots[o, n]
        out[4] = 3 + (slots[w, 1] - slots[o, 1] + 1) + 2 * (slots[w, 2] - slots[o, 2] + 1)
    else:  # inner point below: the inner owns it
        for n in range(4):
            out[n] = slots[w, n]
        out[4] = 3 + (slots[o, 1] - slots[w, 1]) + 2 * (slots[o, 2] - slots[w, 2])


@njit(cache=True, nogil=True)
def _vertex_id(code, slots, edge_ends, vid_o, vid_i, ref_o, ref_i, rec_cut, n_lattice, owner):
    if code < 4:
        return _get(slots[code, 0], slots[code, 1], slots[code, 2], slots[code, 3], vid_o, vid_i)
    _cut_owner(slots, edge_ends[code - 4, 0], edge_ends[code - 4, 1], owner)
    r = _get(owner[0], owner[1], owner[2], owner[3], ref_o, ref_i)
    return n_lattice + rec_cut[r, owner[4]]


@njit(cache=True, nogil=True)
def _row_has_positive(j, k, row_o, row_i):
    nzo, nyo = row_o.shape
    nzi, nyi = row_i.shape
    if row_o[k, j] or (j + 1 < nyo and row_o[k, j + 1]) or (k + 1 < nzo and row_o[k + 1, j]):
        return True
    for dk in range(-1, 1):
        for dj in range(-1, 1):
            if 0 <= k + dk < nzi and 0 <= j + dj < nyi and row_i[k + dk, j + dj]:
                return True
    return False


@njit(cache=True, nogil=True)
def _near_positive(i, j, k, sign_o, sign_i):
    """Whether a point of the twelve tetrahedra about ``O(i, j, k)``'s three outer black edges is positive."""
    nzo, nyo, nxo = sign_o.shape
    nzi, nyi, nxi = sign_i.shape
    if sign_o[k, j, i] > 0:
        return True
    if (i + 1 < nxo and sign_o[k, j, i + 1] > 0) or (j + 1 < nyo and sign_o[k, j + 1, i] > 0) or (
            k + 1 < nzo and sign_o[k + 1, j, i] > 0):
        return True
    for kk in range(k - 1, k + 1):
        for jj in range(j - 1, j + 1):
            for ii in range(i - 1, i + 1):
                if 0 <= kk < nzi and 0 <= jj < nyi and 0 <= ii < nxi and sign_i[kk, jj, ii] > 0:
                    return True
    return False


@njit(cache=True, nogil=True)
def _all_positive(i, j, k, sign_o, sign_i):
    """Whether the twelve tetrahedra about ``O(i, j, k)`` exist and all their vertices are positive (the interior:
    every tetrahedron is kept whole)."""
    nzo, nyo, nxo = sign_o.shape
    nzi, nyi, nxi = sign_i.shape
    if not (1 <= i < nxi and 1 <= j < nyi and 1 <= k < nzi):
        return False
    if sign_o[k, j, i] <= 0 or sign_o[k, j, i + 1] <= 0 or sign_o[k, j + 1, i] <= 0 or sign_o[k + 1, j, i] <= 0:
        return False
    for kk in range(k - 1, k + 1):
        for jj in range(j - 1, j + 1):
            for ii in range(i - 1, i + 1):
                if sign_i[kk, jj, ii] <= 0:
                    return False
    return True


@njit(cache=True, nogil=True)
def _pattern(slots, sign_o, sign_i, on_surface):
    """Sign pattern (-1 without a positive vertex) of a tetrahedron; ``on_surface[s]`` for its zero vertices."""
    pattern = 0
    positive = False
    for s in range(4):
        sign = _get(slots[s, 0], slots[s, 1], slots[s, 2], slots[s, 3], sign_o, sign_i)
        positive |= sign > 0
        on_surface[s] = sign == 0
        pattern = (pattern << 2) | _sign_code(sign)
    return pattern if positive else -1


@njit(cache=True, nogil=True)
def _variant(slots, pattern, faces, n_faces):
    variant = 0
    for f in range(n_faces[pattern]):
        variant |= _parity_bit(slots, faces[pattern, f, 0], faces[pattern, f, 1], faces[pattern, f, 2]) << f
    return variant


@njit(cache=True, nogil=True, parallel=True)
def count(sign_o, sign_i, row_o, row_i, counts, faces, n_faces, surface_faces, ring, row_counts):
    """Output tetrahedra and candidate boundary faces of every row ``(k, j)`` of outer points, into
    ``row_counts[k, j]``."""
    nzo, nyo, nxo = sign_o.shape
    shape_o = sign_o.shape
    shape_i = sign_i.shape
    for k in prange(nzo):
        layer = np.int64(k)  # for the helpers (see algorithms.common.cutaway, compile time)
        slots = np.empty((4, 4), dtype=np.int64)
        on_surface = np.empty(10, dtype=np.bool_)
        for j in range(nyo):
            n_tets = 0
            n_bound = 0
            if _row_has_positive(j, layer, row_o, row_i):
                for i in range(nxo):
                    if not _near_positive(i, j, layer, sign_o, sign_i):
                        continue
                    if _all_positive(i, j, layer, sign_o, sign_i):
                        n_tets += 12
                        continue
                    for axis in range(3):
                        for q in range(4):
                            _vertices(i, j, layer, axis, q, ring, slots)
                            if not _in_range(slots, shape_o, shape_i):
                                continue
                            pattern = _pattern(slots, sign_o, sign_i, on_surface)
                            if pattern < 0:
                                continue
                            n_tets += counts[pattern]
                            n_bound += surface_faces[pattern, _variant(slots, pattern, faces, n_faces)]
            row_counts[k, j, 0] = n_tets
            row_counts[k, j, 1] = n_bound


@njit(cache=True, nogil=True, parallel=True)
def stuff(sign_o, sign_i, vid_o, vid_i, ref_o, ref_i, rec_cut, n_lattice, counts, faces, n_faces, table,
          edge_ends, ring, outward, first, row_counts, tets, boundary):
    """Write the output tetrahedra and the candidate boundary faces (faces whose three vertices lie on the surface,
    oriented outward) of every row ``(k, j)`` of outer points from ``first[k, j] = (tetrahedron, face)``."""
    nzo, nyo, nxo = sign_o.shape
    shape_o = sign_o.shape
    shape_i = sign_i.shape
    for k in prange(nzo):
        layer = np.int64(k)  # for the helpers (see algorithms.common.cutaway, compile time)
        slots = np.empty((4, 4), dtype=np.int64)
        owner = np.empty(5, dtype=np.int64)
        ids = np.empty(10, dtype=np.int64)
        on_surface = np.empty(10, dtype=np.bool_)
        for j in range(nyo):
            if row_counts[k, j, 0] == 0:
                continue
            n_tets = first[k, j, 0]
            n_bound = first[k, j, 1]
            for i in range(nxo):
                if not _near_positive(i, j, layer, sign_o, sign_i):
                    continue
                interior = _all_positive(i, j, layer, sign_o, sign_i)
                for axis in range(3):
                    for q in range(4):
                        _vertices(i, j, layer, axis, q, ring, slots)
                        if interior:
                            for s in range(4):
                                tets[n_tets, s] = _get(slots[s, 0], slots[s, 1], slots[s, 2], slots[s, 3], vid_o,
                                                       vid_i)
                            n_tets += 1
                            continue
                        if not _in_range(slots, shape_o, shape_i):
                            continue
                        pattern = _pattern(slots, sign_o, sign_i, on_surface)
                        if pattern < 0:
                            continue
                        variant = _variant(slots, pattern, faces, n_faces)
                        for c in range(4, 10):
                            on_surface[c] = True
                        for c in range(10):
                            ids[c] = -1
                        for t in range(counts[pattern]):
                            for s in range(4):
                                code = table[pattern, variant, t, s]
                                if ids[code] < 0:
                                    ids[code] = _vertex_id(code, slots, edge_ends, vid_o, vid_i, ref_o, ref_i,
                                                           rec_cut, n_lattice, owner)
                                tets[n_tets, s] = ids[code]
                            n_tets += 1
                            for f in range(4):
                                c0 = table[pattern, variant, t, outward[f, 0]]
                                c1 = table[pattern, variant, t, outward[f, 1]]
                                c2 = table[pattern, variant, t, outward[f, 2]]
                                if on_surface[c0] and on_surface[c1] and on_surface[c2]:
                                    boundary[n_bound, 0] = ids[c0]
                                    boundary[n_bound, 1] = ids[c1]
                                    boundary[n_bound, 2] = ids[c2]
                                    n_bound += 1
