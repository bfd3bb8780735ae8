"""numba kernels of the tower algorithm (see :mod:`algorithms.surfaces.tower.core` for the method).

The solid mask is padded by one empty voxel on every side: voxel ``(i, j, k)`` is ``solid[k + 1, j + 1, i + 1]``,
so the kernels read the neighbours of border voxels (outside = empty) without bounds checks. Work is split into
*units*: unit ``k`` emits the circumference strips of slice ``k`` (``k < nz``) and the top and bottom strips on the
interface below slice ``k``. Every kernel runs twice with the same walk: counting (``write`` False) and writing
each unit into its own exact range of the output.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Codes of :attr:`algorithms.surfaces.tower.TowerStrips.kinds`.
STRIP_CIRCUMFERENCE, STRIP_TOP, STRIP_BOTTOM = 0, 1, 2

# Walking directions in the slice, clockwise seen from +z, so that turning right is ``(d + 1) % 4``:
# 0 = +x, 1 = -y, 2 = -x, 3 = +y.
_STEP_X = np.array([1, 0, -1, 0], dtype=np.int64)
_STEP_Y = np.array([0, -1, 0, 1], dtype=np.int64)


def _successor_table() -> np.ndarray:
    """``table[code, d]``: the direction taken at a corner after arriving in direction ``d`` (-1: no edge).

    ``code`` holds the four voxels around the corner: bit 0 = (cx-1, cy-1), 1 = (cx, cy-1), 2 = (cx-1, cy),
    3 = (cx, cy). The edge leaving in direction ``d`` exists when the voxel on its right (seen from +z) is solid and
    the one on its left empty; turning right is tried first, then straight on, then left, which keeps voxels that
    touch only diagonally in separate loops (4-connected clusters).
    """
    right_left = {0: (1, 3), 1: (0, 1), 2: (2, 0), 3: (3, 2)}  # direction -> (bit on its right, bit on its left)
    table = np.full((16, 4), -1, dtype=np.int64)
    for code in range(16):
        for arriving in range(4):
            for turn in (1, 0, 3):
                leaving = (arriving + turn) % 4
                right, left = right_left[leaving]
                if code >> right & 1 and not code >> left & 1:
                    table[code, arriving] = leaving
                    break
    return table


_SUCCESSOR = _successor_table()


@njit(cache=True, nogil=True, inline="always")
def _at(solid, k, j, i):
    """Whether voxel ``(i, j, k)`` is solid, for ``-1 <= i <= nx`` etc. (``solid`` is padded by one empty voxel)."""
    return solid[k + 1, j + 1, i + 1]


@njit(cache=True, nogil=True, inline="always")
def _corner_code(solid, k, cx, cy):
    """The four voxels of slice ``k`` around corner ``(cx, cy)`` as bits (see :func:`_successor_table`)."""
    return (
        _at(solid, k, cy - 1, cx - 1)
        | (_at(solid, k, cy - 1, cx) << 1)
        | (_at(solid, k, cy, cx - 1) << 2)
        | (_at(solid, k, cy, cx) << 3)
    )


@njit(cache=True, nogil=True, inline="always")
def _put_pair(points, v, x0, y0, z0, x1, y1, z1, write):
    """Write vertices ``v`` and ``v + 1`` (when ``write``); returns ``v + 2``."""
    if write:
        points[v, 0] = x0
        points[v, 1] = y0
        points[v, 2] = z0
        points[v + 1, 0] = x1
        points[v + 1, 1] = y1
        points[v + 1, 2] = z1
    return v + 2


@njit(cache=True, nogil=True, inline="always")
def _end_strip(lengths, kinds, s, length, kind, write):
    """Record strip ``s`` (when ``write``); returns ``s + 1``."""
    if write:
        lengths[s] = length
        kinds[s] = kind
    return s + 1


@njit(cache=True, nogil=True)
def _circumferences(solid, k, geometry, points, v, lengths, kinds, s, write):
    """Emit one strip per boundary loop of slice ``k`` from slots ``v``, ``s``; returns the next free slots."""
    ny, nx = solid.shape[1] - 2, solid.shape[2] - 2
    ox, oy, oz, sx, sy, sz = geometry
    z_bottom = oz + sz * (k - 0.5)
    z_top = oz + sz * (k + 0.5)
    visited = np.zeros((ny, nx), dtype=np.uint8)  # bit d: the face walked in direction d has been drawn
    for j in range(ny):
        for i in range(nx):
            if not _at(solid, k, j, i):
                continue
            # Bit d: the side face walked in direction d (0 = +y face, 1 = +x, 2 = -y, 3 = -x) is exposed.
            exposed = (
                (not _at(solid, k, j + 1, i))
                | ((not _at(solid, k, j, i + 1)) << 1)
                | ((not _at(solid, k, j - 1, i)) << 2)
                | ((not _at(solid, k, j, i - 1)) << 3)
            )
            for face in range(4):
                if not (exposed & ~visited[j, i]) >> face & 1:
                    continue
                # The walk along this face starts at its first corner (solid on the right).
                cx = i + (face == 1 or face == 2)
                cy = j + (face == 0 or face == 1)
                start_x, start_y, start_d = cx, cy, face
                first = v
                d = face
                while True:
                    x = ox + sx * (cx - 0.5)
                    y = oy + sy * (cy - 0.5)
                    v = _put_pair(points, v, x, y, z_bottom, x, y, z_top, write)
                    if v - first > 2 and cx == start_x and cy == start_y and d == start_d:
                        break  # the start corner written again closes the loop
                    # Mark the face of the edge about to be walked, at the voxel on its right.
                    if d == 0:
                        visited[cy - 1, cx] |= 1
                    elif d == 1:
                        visited[cy - 1, cx - 1] |= 2
                    elif d == 2:
                        visited[cy, cx - 1] |= 4
                    else:
                        visited[cy, cx] |= 8
                    cx += _STEP_X[d]
                    cy += _STEP_Y[d]
                    d = _SUCCESSOR[_corner_code(solid, k, cx, cy), d]
                s = _end_strip(lengths, kinds, s, v - first, STRIP_CIRCUMFERENCE, write)
    return v, s


@njit(cache=True, nogil=True)
def _run_strip(points, v, lengths, kinds, s, geometry, first_i, end_i, j, k, top, write):
    """Emit and record the strip of faces ``first_i .. end_i - 1`` of row ``j`` between slices k-1 and k (top
    faces of slice k-1 when ``top``, else bottom faces of slice k); returns the next free slots ``v``, ``s``."""
    ox, oy, oz, sx, sy, sz = geometry
    z = oz + sz * (k - 0.5)
    y_low = oy + sy * (j - 0.5)
    y_high = oy + sy * (j + 0.5)
    first = v
    for c in range(first_i, end_i + 1):
        x = ox + sx * (c - 0.5)
        if top:  # (x, y+), (x, y-): the first triangle faces +z
            v = _put_pair(points, v, x, y_high, z, x, y_low, z, write)
        else:  # pairs swapped: the first triangle faces -z
            v = _put_pair(points, v, x, y_low, z, x, y_high, z, write)
    s = _end_strip(lengths, kinds, s, v - first, STRIP_TOP if top else STRIP_BOTTOM, write)
    return v, s


@njit(cache=True, nogil=True)
def _sides(solid, k, geometry, points, v, lengths, kinds, s, write):
    """Emit the top strips of slice k-1 and bottom strips of slice k on the rows where the slices differ."""
    ny, nx = solid.shape[1] - 2, solid.shape[2] - 2
    for j in range(ny):
        differs = False  # the discrepancy test of the source: does this row differ between the slices?
        for i in range(nx):
            if _at(solid, k - 1, j, i) != _at(solid, k, j, i):
                differs = True
                break
        if not differs:
            continue
        # Typed values, not literal constants, for the arguments of _run_strip: numba would compile it once for
        # each literal argument.
        top_first = np.int64(-1)
        bottom_first = np.int64(-1)
        upper, lower = np.bool_(True), np.bool_(False)
        for i in range(nx + 1):
            below = _at(solid, k - 1, j, i)  # i == nx reads the empty padding and ends every run
            above = _at(solid, k, j, i)
            top = below and not above
            bottom = above and not below
            if top and top_first < 0:
                top_first = i
            elif not top and top_first >= 0:
                v, s = _run_strip(points, v, lengths, kinds, s, geometry, top_first, i, j, k, upper, write)
                top_first = -1
            if bottom and bottom_first < 0:
                bottom_first = i
            elif not bottom and bottom_first >= 0:
                v, s = _run_strip(points, v, lengths, kinds, s, geometry, bottom_first, i, j, k, lower, write)
                bottom_first = -1
    return v, s


@njit(cache=True, nogil=True, parallel=True)
def walk_units(solid, geometry, first, last, points, lengths, kinds, vertex_slots, strip_slots, write):
    """Run units ``first .. last - 1`` in parallel.

    Counting (``write`` False): store each unit's vertex and strip counts in ``vertex_slots``/``strip_slots``.
    Writing: unit ``u`` writes from vertex ``vertex_slots[u]`` and strip ``strip_slots[u]`` on.
    """
    nz = solid.shape[0] - 2
    for unit in prange(first, last):
        v = vertex_slots[unit] if write else 0
        s = strip_slots[unit] if write else 0
        if unit < nz:
            v, s = _circumferences(solid, unit, geometry, points, v, lengths, kinds, s, write)
        v, s = _sides(solid, unit, geometry, points, v, lengths, kinds, s, write)
        if not write:
            vertex_slots[unit] = v
            strip_slots[unit] = s
