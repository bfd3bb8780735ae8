"""numba kernels of marching cubes, and Bourke's tables in the form they use (see :mod:`.core` for the method).

Implementation (parallel over k slices or over vertices; no Python loop per cell):

1. :func:`classify_layers`: classify every sample (an inside mask), note per row of cells the span of columns
   where anything happens, and count the cut edges of each slice and the triangles of each layer of cells.
2. Prefix sums of the counts (in :mod:`.core`) give every slice its first vertex id and every layer its first
   triangle.
3. :func:`fill_slabs`: slabs of layers, balanced by work, run independently: each numbers the cut edges of its
   slices in a fixed order into small per-slice id planes (so each cut edge gets exactly one vertex, without
   hashing), records each vertex's edge, and writes its layers' triangles by looking the ids up.
4. :func:`vertex_attributes` computes positions (and normals) per vertex from its edge;
   :func:`merge_on_samples` merges vertices that fall on the same sample.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import tables

def _column_pair_cases() -> np.ndarray:
    """Bourke case of a cell from the inside bits of its two corner columns, indexed ``low | high << 4``.

    A column holds the four samples of one ``i``: bit ``dj + 2 dk`` is set when the sample ``(j + dj, k + dk)``
    is inside (``value >= iso``). ``low`` is the column at ``i``, ``high`` at ``i + 1``. Bourke's case sets the
    bits of the corners *below* the isovalue, hence the complement.
    """
    pair = np.arange(256)
    low, high = pair & 15, pair >> 4
    inside = np.zeros(256, dtype=np.int64)
    for corner, (di, dj, dk) in enumerate(tables.CORNER_OFFSETS):
        inside |= (((high if di else low) >> (dj + 2 * dk)) & 1) << corner
    return (255 - inside).astype(np.uint8)


def _edge_slots() -> np.ndarray:
    """Where the kernels keep the vertex id of each cell edge, shape (12, 4): ``(level, axis, dj, di)``.

    For the cell ``(i, j)`` of the layer between slices k and k + 1, an x or y edge (axis 0 or 1) lies in slice
    k (level 0) or k + 1 (level 1) at row ``j + dj``, column ``i + di``; z edges (level 2, axis 2) join the two.
    """
    slots = np.empty((12, 4), dtype=np.int64)
    for edge, (a, b) in enumerate(tables.EDGE_CORNERS):
        start = np.minimum(tables.CORNER_OFFSETS[a], tables.CORNER_OFFSETS[b])
        axis = int(np.flatnonzero(tables.CORNER_OFFSETS[a] != tables.CORNER_OFFSETS[b])[0])
        level = 2 if axis == 2 else int(start[2])
        slots[edge] = (level, axis, start[1], start[0])
    return slots


def _triangle_counts() -> np.ndarray:
    """Number of triangles of each case of the triangle table, shape (256,)."""
    padded = np.c_[tables.TRIANGLE_TABLE, np.full(256, -1, dtype=tables.TRIANGLE_TABLE.dtype)]
    return (np.argmax(padded < 0, axis=1) // 3).astype(np.int64)


#: Bourke case of a cell from its two corner columns' inside bits, ``PAIR_CASE[low | high << 4]``.
PAIR_CASE = _column_pair_cases()
#: Where the kernels keep each cell edge's vertex id: ``(level, axis, dj, di)`` per edge.
EDGE_SLOTS = _edge_slots()
#: Bourke's triangle table as int64 edge numbers (padded with -1).
TRIANGLES = tables.TRIANGLE_TABLE.astype(np.int64)
#: Triangles of each case.
TRIANGLE_COUNT = _triangle_counts()
#: Set bits of each 4-bit number.
POPCOUNT4 = np.array([bin(v).count("1") for v in range(16)], dtype=np.int64)


# ``threshold`` is the isovalue in the volume's own number type such that ``value >= threshold`` exactly when ``value >=
# iso`` (see :func:`algorithms.surfaces.marching_cubes.core._inside_threshold`); comparing in the native type lets LLVM
# vectorise the scans.
# ``inside[k, j, i]`` is 1 where the sample is inside, 0 elsewhere: after the first pass only the vertex
# positions and normals read the volume, so the other kernels are compiled once, whatever its dtype.
# ``spans[k, j]`` is the inclusive range of sample columns ``i`` where anything happens in the row of cells
# ``(j, k)``: a column whose four samples are not all on one side, or that differs from its neighbour. Every cut
# edge of the four sample rows of that row of cells, and every cell with triangles, lies inside the span.


@njit(cache=True, nogil=True, parallel=True)
def classify_layers(volume, threshold, start, stop, pair_case, triangle_count, popcount, inside, spans, counts):
    """Inside mask, row spans and per-slice counts of the cell layers ``start..stop-1``.

    ``counts[k]``: cut x and y edges in slice k, cut z edges between slices k and k + 1, triangles of layer k,
    and whether a sample of slice k is NaN. The last layer also fills ``inside[nz - 1]`` and ``counts[nz - 1]``.
    """
    nz, ny, nx = volume.shape
    for k in prange(start, stop):
        top = k == nz - 2  # the last layer also counts the x and y edges of the last slice
        planar = 0
        vertical = 0
        triangles = 0
        planar_top = 0
        undefined = False
        codes = np.empty(nx, dtype=np.uint8)
        for j in range(ny - 1):
            last_row = j == ny - 2  # the last row of cells also owns the last row of samples
            rows = 3 if last_row else 1  # sample rows this row of cells counts (bit 0: j, bit 1: j + 1)
            rows_top = rows if top else 0
            a0 = volume[k, j]
            a1 = volume[k, j + 1]
            b0 = volume[k + 1, j]
            b1 = volume[k + 1, j + 1]
            mask = inside[k, j]
            # Column codes: bit dj + 2 dk is set when sample (j + dj, k + dk) of the column is inside.
            lowest = 15
            highest = 0
            for i in range(nx):
                code = (a0[i] >= threshold) + 2 * (a1[i] >= threshold) + 4 * (b0[i] >= threshold) + 8 * (
                    b1[i] >= threshold
                )
                codes[i] = code
                mask[i] = code & 1
                lowest = min(lowest, code)
                highest = max(highest, code)
                undefined |= a0[i] != a0[i]
            if last_row or top:
                for i in range(nx):
                    if last_row:
                        inside[k, j + 1, i] = (codes[i] >> 1) & 1
                    if top:
                        inside[k + 1, j, i] = (codes[i] >> 2) & 1
                    if last_row and top:
                        inside[k + 1, j + 1, i] = codes[i] >> 3
            if lowest == highest and (lowest == 0 or lowest == 15):  # all samples of the row on one side
                spans[k, j, 0] = nx
                spans[k, j, 1] = -1
                continue
            # The span: from the first to the last column that is mixed or differs from its neighbour.
            low = 0
            while (codes[low] == 0 or codes[low] == 15) and codes[low] == codes[low + 1]:
                low += 1
            high = nx - 1
            while (codes[high] == 0 or codes[high] == 15) and codes[high] == codes[high - 1]:
                high -= 1
            spans[k, j, 0] = low
            spans[k, j, 1] = high
            previous = np.int64(codes[low])
            for i in range(low, high + 1):
                code = np.int64(codes[i])
                if code == previous and (code == 0 or code == 15) and i > low:
                    continue  # a column and a cell with all samples on one side
                across_y = code ^ (code >> 1)  # bit 0: y edge in slice k, bit 2: y edge in slice k + 1
                planar += across_y & 1
                planar_top += (across_y >> 2) & np.int64(top)
                vertical += popcount[(code ^ (code >> 2)) & rows]  # z edges of sample rows j (and j + 1)
                if i > low:
                    across_x = previous ^ code  # x edges: bits 0, 1 in slice k, bits 2, 3 in slice k + 1
                    planar += popcount[across_x & rows]
                    planar_top += popcount[(across_x >> 2) & rows_top]
                    triangles += triangle_count[pair_case[previous | (code << 4)]]
                previous = code
        last_row_samples = volume[k, ny - 1]
        for i in range(nx):
            undefined |= last_row_samples[i] != last_row_samples[i]
        counts[k, 0] = planar
        counts[k, 1] = vertical
        counts[k, 2] = triangles
        counts[k, 3] = undefined
        if top:
            for j in range(ny):
                row = volume[k + 1, j]
                for i in range(nx):
                    undefined |= row[i] != row[i]
            counts[k + 1, 0] = planar_top
            counts[k + 1, 1] = 0
            counts[k + 1, 2] = 0
            counts[k + 1, 3] = undefined


@njit(cache=True, nogil=True)
def _edge_code(k, j, i, axis):
    """An edge as one int64: its lower sample (i, j, k) and axis (0, 1, 2 for x, y, z) packed in bit fields.

    Bits 0-1 axis, 2-17 i, 18-33 j, 34 and up k: shifts instead of divisions to unpack (``nx, ny <= 65536``).
    """
    return (np.int64(k) << 34) | (np.int64(j) << 18) | (np.int64(i) << 2) | axis


@njit(cache=True, nogil=True, inline="always")
def _row_span(spans, layer, j):
    """``(low, high)``: the columns of sample row ``j`` of a layer's lower (or, for the last layer, upper) slice
    where edges can be cut (the span of the row of cells below it, or above it for the last row)."""
    cells = min(j, spans.shape[1] - 1)
    return spans[layer, cells, 0], spans[layer, cells, 1]


@njit(cache=True, nogil=True, inline="always")
def _number_across(row, other, low, high, ids, vertex, code, write, vertex_edges):
    """Number the edges from ``row[i]`` to ``other[i]`` (``i = low .. high``) that are cut, from ``vertex`` on.

    The ids go to ``ids[i]``; with ``write``, edge ``i`` is recorded as ``code | (i << 2)`` (``code``: the
    :func:`_edge_code` of the row's first edge). Returns the next free id.
    """
    for i in range(low, high + 1):
        if row[i] != other[i]:
            ids[i] = vertex
            if write:
                vertex_edges[vertex] = code | (i << 2)
            vertex += 1
    return vertex


@njit(cache=True, nogil=True)
def _slice_vertices(inside, k, first, spans, x_ids, y_ids, write, vertex_edges):
    """Number the cut x and y edges of slice k from ``first`` (row by row: x edges, then y edges).

    The ids go to ``x_ids[j, i]`` and ``y_ids[j, i]`` (at the edge's lower sample). With ``write``, each
    vertex's edge is recorded in ``vertex_edges[id]`` (see :func:`_edge_code`). Returns the next free id.
    """
    nz, ny, nx = inside.shape
    span_layer = min(k, nz - 2)
    vertex = first
    for j in range(ny):
        low, high = _row_span(spans, span_layer, j)
        row_code = _edge_code(k, j, 0, 0)
        row = inside[k, j]
        for i in range(low, high):
            if row[i] != row[i + 1]:
                x_ids[j, i] = vertex
                if write:
                    vertex_edges[vertex] = row_code | (i << 2)
                vertex += 1
        if j + 1 < ny:
            vertex = _number_across(row, inside[k, j + 1], low, high, y_ids[j], vertex, row_code | 1, write,
                                    vertex_edges)
    return vertex


@njit(cache=True, nogil=True)
def _vertical_vertices(inside, k, first, spans, ids, vertex_edges):
    """Number the cut z edges between slices k and k + 1 from ``first`` and record their edges."""
    nz, ny, nx = inside.shape
    vertex = first
    for j in range(ny):
        low, high = _row_span(spans, k, j)
        vertex = _number_across(inside[k, j], inside[k + 1, j], low, high, ids[j], vertex, _edge_code(k, j, 0, 2),
                                True, vertex_edges)


@njit(cache=True, nogil=True)
def _layer_triangles(inside, spans, k, first, ids, edge_offsets, pair_case, triangle_table, triangle_count,
                     triangles):
    """Write the triangles of layer k from ``first``.

    ``ids`` holds the id planes of the layer flat; the vertex of edge ``e`` of cell (i, j) is
    ``ids[edge_offsets[e] + j * nx + i]``.
    """
    nz, ny, nx = inside.shape
    row = first
    for j in range(ny - 1):
        low = spans[k, j, 0]
        high = spans[k, j, 1]
        if low >= high:
            continue
        a0 = inside[k, j]
        a1 = inside[k, j + 1]
        b0 = inside[k + 1, j]
        b1 = inside[k + 1, j + 1]
        previous = np.int64(a0[low]) | (np.int64(a1[low]) << 1) | (np.int64(b0[low]) << 2) | (np.int64(b1[low]) << 3)
        for i in range(low, high):
            code = (np.int64(a0[i + 1]) | (np.int64(a1[i + 1]) << 1) | (np.int64(b0[i + 1]) << 2)
                    | (np.int64(b1[i + 1]) << 3))
            case = pair_case[previous | (code << 4)]
            previous = code
            cell = j * nx + i
            for t in range(triangle_count[case]):
                triangles[row, 0] = ids[edge_offsets[triangle_table[case, 3 * t]] + cell]
                triangles[row, 1] = ids[edge_offsets[triangle_table[case, 3 * t + 1]] + cell]
                triangles[row, 2] = ids[edge_offsets[triangle_table[case, 3 * t + 2]] + cell]
                row += 1


@njit(cache=True, nogil=True, parallel=True)
def fill_slabs(inside, bounds, vertex_first, planar_counts, triangle_first, spans, pair_case, triangle_table,
                triangle_count, edge_slots, vertex_edges, triangles):
    """Number the vertices and write the triangles of the slabs of layers ``bounds[s]..bounds[s+1]-1``.

    One slab per iteration. Slice k's x/y vertices are recorded by the slab holding layer k (the last slice by
    the last slab); a slab also numbers the x/y edges of the slice above its last layer, to use their ids.
    """
    nz, ny, nx = inside.shape
    plane = ny * nx
    for slab in prange(bounds.shape[0] - 1):
        first_layer = bounds[slab]
        stop_layer = bounds[slab + 1]
        if first_layer >= stop_layer:
            continue
        # Five id planes: the x and y edges of slices of even and odd k (plane 2 * parity + axis), the z edges.
        ids = np.empty(5 * plane, dtype=np.int64)
        edge_offsets = np.empty(12, dtype=np.int64)
        parity = first_layer & 1
        _slice_vertices(inside, first_layer, vertex_first[first_layer], spans,
                        ids[2 * parity * plane:(2 * parity + 1) * plane].reshape((ny, nx)),
                        ids[(2 * parity + 1) * plane:(2 * parity + 2) * plane].reshape((ny, nx)), True, vertex_edges)
        for k in range(first_layer, stop_layer):
            _vertical_vertices(inside, k, vertex_first[k] + planar_counts[k], spans, ids[4 * plane:].reshape((ny, nx)),
                               vertex_edges)
            lower = k & 1
            upper = 1 - lower
            _slice_vertices(inside, k + 1, vertex_first[k + 1], spans,
                            ids[2 * upper * plane:(2 * upper + 1) * plane].reshape((ny, nx)),
                            ids[(2 * upper + 1) * plane:(2 * upper + 2) * plane].reshape((ny, nx)),
                            k + 1 < stop_layer or k + 1 == nz - 1, vertex_edges)
            for edge in range(12):
                level, axis, dj, di = edge_slots[edge, 0], edge_slots[edge, 1], edge_slots[edge, 2], edge_slots[edge, 3]
                index = 4 if level == 2 else 2 * (lower if level == 0 else upper) + axis
                edge_offsets[edge] = index * plane + dj * nx + di
            _layer_triangles(inside, spans, k, triangle_first[k], ids, edge_offsets, pair_case, triangle_table,
                             triangle_count, triangles)


@njit(cache=True, nogil=True)
def _edge_ends(code):
    """Sample indices ``(k, j, i)`` of both ends of the edge with this :func:`_edge_code`, and its axis."""
    axis = code & 3
    i = (code >> 2) & 0xFFFF
    j = (code >> 18) & 0xFFFF
    k = code >> 34
    return k, j, i, k + (axis == 2), j + (axis == 1), i + (axis == 0), axis


@njit(cache=True, nogil=True)
def _central_difference(volume, k, j, i, axis, axis_spacing):
    """Derivative along ``axis`` at sample (i, j, k) per mm (``axis_spacing`` mm between samples): central,
    one-sided at the volume border."""
    nz, ny, nx = volume.shape
    if axis == 0:
        low, high = max(i - 1, 0), min(i + 1, nx - 1)
        a, b = volume[k, j, low], volume[k, j, high]
    elif axis == 1:
        low, high = max(j - 1, 0), min(j + 1, ny - 1)
        a, b = volume[k, low, i], volume[k, high, i]
    else:
        low, high = max(k - 1, 0), min(k + 1, nz - 1)
        a, b = volume[low, j, i], volume[high, j, i]
    return (np.float64(b) - np.float64(a)) / (axis_spacing * (high - low))


@njit(cache=True, nogil=True, parallel=True)
def vertex_attributes(volume, iso, vertex_edges, spacing, origin, points, normals, on_sample):
    """Position (and, if ``normals`` is not empty, normal) of each vertex from its edge.

    Positions interpolate linearly from the edge's lower sample; ``on_sample[v]`` is the flat index of the sample
    a vertex falls on exactly, else -1. Normals are the negated gradient interpolated along the edge, normalised
    (zero where the gradient vanishes).
    """
    nz, ny, nx = volume.shape
    for vertex in prange(vertex_edges.shape[0]):
        k, j, i, k1, j1, i1, axis = _edge_ends(vertex_edges[vertex])
        v0 = np.float64(volume[k, j, i])
        t = (iso - v0) / (np.float64(volume[k1, j1, i1]) - v0)
        points[vertex, 0] = origin[0] + spacing[0] * (i + t if axis == 0 else np.float64(i))
        points[vertex, 1] = origin[1] + spacing[1] * (j + t if axis == 1 else np.float64(j))
        points[vertex, 2] = origin[2] + spacing[2] * (k + t if axis == 2 else np.float64(k))
        if t == 0.0:
            on_sample[vertex] = (k * ny + j) * nx + i
        elif t == 1.0:
            on_sample[vertex] = (k1 * ny + j1) * nx + i1
        else:
            on_sample[vertex] = -1
        if normals.shape[0] > 0:
            g0 = _central_difference(volume, k, j, i, 0, spacing[0])
            x = -(g0 + t * (_central_difference(volume, k1, j1, i1, 0, spacing[0]) - g0))
            g0 = _central_difference(volume, k, j, i, 1, spacing[1])
            y = -(g0 + t * (_central_difference(volume, k1, j1, i1, 1, spacing[1]) - g0))
            g0 = _central_difference(volume, k, j, i, 2, spacing[2])
            z = -(g0 + t * (_central_difference(volume, k1, j1, i1, 2, spacing[2]) - g0))
            length = np.sqrt(x * x + y * y + z * z)
            scale = 1.0 / length if length > 0.0 else 0.0
            normals[vertex, 0] = x * scale
            normals[vertex, 1] = y * scale
            normals[vertex, 2] = z * scale


@njit(cache=True, nogil=True)
def merge_on_samples(points, normals, on_sample, triangles):
    """Share one vertex among the cut edges whose vertex fell exactly on the same sample; drop collapsed triangles.

    Works in place: each group of vertices on one sample keeps its lowest id; the freed ids below the new count
    are filled by moving the last vertices down, and triangles are renumbered (those left with two equal vertices
    are dropped). Returns the new numbers of points and triangles (the arrays' leading parts).
    """
    flagged = np.nonzero(on_sample >= 0)[0]
    if flagged.shape[0] == 0:
        return points.shape[0], triangles.shape[0]
    order = np.argsort(on_sample[flagged], kind="mergesort")  # stable: each group's lowest id first
    new_id = np.arange(points.shape[0])
    leader = np.empty(flagged.shape[0], dtype=np.int64)
    freed = np.zeros(points.shape[0], dtype=np.bool_)
    holes = 0
    for n in range(order.shape[0]):
        vertex = flagged[order[n]]
        if n > 0 and on_sample[vertex] == on_sample[flagged[order[n - 1]]]:
            leader[n] = leader[n - 1]
            freed[vertex] = True
            holes += 1
        else:
            leader[n] = vertex
    count = points.shape[0] - holes
    mover = count
    for hole in range(count):  # fill freed ids below the new count with the kept vertices above it
        if freed[hole]:
            while freed[mover]:
                mover += 1
            points[hole] = points[mover]
            if normals.shape[0] > 0:
                normals[hole] = normals[mover]
            new_id[mover] = hole
            mover += 1
    for n in range(order.shape[0]):
        new_id[flagged[order[n]]] = new_id[leader[n]]
    kept = 0
    for row in range(triangles.shape[0]):
        a = new_id[triangles[row, 0]]
        b = new_id[triangles[row, 1]]
        c = new_id[triangles[row, 2]]
        if a != b and b != c and a != c:
            triangles[kept, 0] = a
            triangles[kept, 1] = b
            triangles[kept, 2] = c
            kept += 1
    return count, kept
