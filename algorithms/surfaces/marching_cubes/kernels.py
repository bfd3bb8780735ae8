"""numba kernels of marching cubes, and Bourke's tables in the form they use (see :mod:`.core` for the method).

Implementation: two passes over the rows of cells, both parallel over layers of cells (slabs of consecutive
``k``); no Python loop per cell, no inside mask of the whole volume, no hashing of edges.

1. :func:`count_layers`: classify the samples of each row of cells ``(j, k)`` against the isovalue, note the span
   of columns where anything happens, and count the triangles of the row and the cut edges of the *edge rows* it
   owns. An edge row is the set of x, y or z edges that start on one row of samples ``(j, k)``; each edge row is
   owned by exactly one row of cells (:func:`_owned`).
2. Prefix sums of the counts (in :mod:`.core`) give every edge row its first vertex id and every row of cells its
   first triangle: the cut edges of an edge row are numbered in increasing ``i`` from there. So every cell can
   name the vertices of its edges from eight running counters while it walks along ``i``, and the two rows of
   cells sharing an edge row number it alike without talking to each other (the idea of flying edges, Schroeder,
   Maynard and Geveci 2015).
3. :func:`fill_layers`: walk the same spans again, write each row of cells' triangles, and place the vertices of
   the edge rows it owns (position, and the normal from central differences when asked) while the samples are in
   cache. A vertex that falls exactly on a sample is flagged for :func:`merge_on_samples`.

Threads: each pass is one numba parallel region of one iteration per thread, and the threads take work items
(layers, or slabs of layers) from a shared counter, one at a time (:func:`algorithms.common.atomics.take`, an atomic fetch-and-add) until
none is left. A thread that the operating system slows down, or whose layers happen to be busy ones, simply takes
fewer items: the split adapts while the pass runs, which a split fixed in advance (numba's ``prange``
chunks are dealt out statically) cannot do. Any split gives the same output, since every row of cells knows where
its vertices and triangles go from the prefix sums.

Work memory besides the output: the spans and the per-row counts (a few bytes per row of samples), and a row of
column codes per thread. The kernels take a block of samples and its place in the volume (``origin``) only, so a
block of a larger volume can be meshed on its own.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ...common.atomics import take as _take
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
    """Where a cell finds the vertex id of each of its edges in its 12-slot id list, shape (12,).

    A cell keeps the ids of the edges it touches as ``x[0..3]`` (its x edges on sample rows ``(j, k)``,
    ``(j + 1, k)``, ``(j, k + 1)``, ``(j + 1, k + 1)``), ``y[s][c]`` (y edges in slice ``k + s`` at column
    ``i + c``) and ``z[r][c]`` (z edges on sample row ``j + r`` at column ``i + c``), flattened as
    ``x0..x3, y00, y01, y10, y11, z00, z01, z10, z11``.
    """
    slots = np.empty(12, dtype=np.int64)
    for edge, (a, b) in enumerate(tables.EDGE_CORNERS):
        start = np.minimum(tables.CORNER_OFFSETS[a], tables.CORNER_OFFSETS[b])
        axis = int(np.flatnonzero(tables.CORNER_OFFSETS[a] != tables.CORNER_OFFSETS[b])[0])
        di, dj, dk = (int(v) for v in start)
        if axis == 0:
            slots[edge] = dj + 2 * dk
        elif axis == 1:
            slots[edge] = 4 + 2 * dk + di
        else:
            slots[edge] = 8 + 2 * dj + di
    return slots


def _triangle_counts() -> np.ndarray:
    """Number of triangles of each case of the triangle table, shape (256,)."""
    padded = np.c_[tables.TRIANGLE_TABLE, np.full(256, -1, dtype=tables.TRIANGLE_TABLE.dtype)]
    return (np.argmax(padded < 0, axis=1) // 3).astype(np.int64)


#: Bourke case of a cell from its two corner columns' inside bits, ``PAIR_CASE[low | high << 4]``.
PAIR_CASE = _column_pair_cases()
#: Slot of each cell edge in a cell's 12 vertex ids (see :func:`_edge_slots`).
EDGE_SLOTS = _edge_slots()
#: Bourke's triangle table as the cells' id slots of the triangles' vertices (padded with -1).
TRIANGLES = np.where(tables.TRIANGLE_TABLE >= 0, EDGE_SLOTS[np.maximum(tables.TRIANGLE_TABLE, 0)], -1).astype(np.int64)
#: Triangles of each case.
TRIANGLE_COUNT = _triangle_counts()

# ``threshold`` is the isovalue in the volume's own number type such that ``value >= threshold`` exactly when
# ``value >= iso`` (see :func:`algorithms.surfaces.marching_cubes.core._inside_threshold`); comparing in the native
# type lets LLVM vectorise the scans.
# ``spans[k, j]`` is the inclusive range of sample columns ``i`` where anything happens in the row of cells
# ``(j, k)``: a column whose four samples are not all on one side, or that differs from its neighbour. Every cut
# edge of the four sample rows of that row of cells, and every cell with triangles, lies inside the span; an empty
# row has ``low > high``.
# ``edge_counts[k, j, a]`` counts the cut edges along axis ``a`` (0, 1, 2 for x, y, z) that start on sample row
# ``(j, k)``; ``vertex_first`` has the same layout and holds the id of the first of them.


@njit(cache=True, nogil=True, forceinline=True)
def _owned(j, k, ny, nz):
    """Which edge rows the row of cells ``(j, k)`` owns besides its own x, y and z rows at ``(j, k)``:
    the sample row ``j + 1`` (last row of cells), the slice ``k + 1`` (last layer), or both."""
    return j == ny - 2, k == nz - 2


@njit(cache=True, nogil=True, inline="always")
def _column_codes(volume, threshold, k, j, codes):
    """Column codes of the row of cells ``(j, k)`` into ``codes`` (bit ``dj + 2 dk``: sample ``(j + dj, k + dk)``
    inside); returns the lowest and highest code and whether the sample row ``(j, k)`` holds a NaN."""
    nx = volume.shape[2]
    a0 = volume[k, j]
    a1 = volume[k, j + 1]
    b0 = volume[k + 1, j]
    b1 = volume[k + 1, j + 1]
    lowest = 15
    highest = 0
    undefined = False
    for i in range(nx):
        code = (a0[i] >= threshold) + 2 * (a1[i] >= threshold) + 4 * (b0[i] >= threshold) + 8 * (b1[i] >= threshold)
        codes[i] = code
        lowest = min(lowest, code)
        highest = max(highest, code)
        undefined |= a0[i] != a0[i]
    return lowest, highest, undefined


@njit(cache=True, nogil=True)
def _row_has_nan(row):
    undefined = False
    for i in range(row.shape[0]):
        undefined |= row[i] != row[i]
    return undefined


@njit(cache=True, nogil=True, parallel=True)
def count_layers(volume, threshold, start, stop, parts, pair_case, triangle_count, spans, edge_counts,
                 triangle_counts, flags):
    """Spans, owned cut-edge counts and triangle counts of the rows of cells of layers ``start..stop-1``.

    ``parts`` threads take the layers one at a time from a shared counter (module notes). ``flags[k]`` is set
    when a sample of slice k is NaN (the last layer also checks the last slice). ``edge_counts`` must start at
    zero; ``triangle_counts`` has shape ``(nz - 1, ny - 1)``.
    """
    nz, ny, nx = volume.shape
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):
        codes = np.empty(nx, dtype=np.uint8)
        while True:
            k = start + _take(queue, 1)
            if k >= stop:
                break
            _count_layer(volume, threshold, k, pair_case, triangle_count, spans, edge_counts, triangle_counts,
                         flags, codes)


@njit(cache=True, nogil=True)
def _count_layer(volume, threshold, k, pair_case, triangle_count, spans, edge_counts, triangle_counts, flags,
                 codes):
    """:func:`count_layers` for one layer of cells."""
    nz, ny, nx = volume.shape
    undefined = False
    for j in range(ny - 1):
        last_row, top = _owned(j, k, ny, nz)
        lowest, highest, nan_row = _column_codes(volume, threshold, k, j, codes)
        undefined |= nan_row
        if lowest == highest and (lowest == 0 or lowest == 15):  # all samples of the row on one side
            spans[k, j, 0] = nx
            spans[k, j, 1] = -1
            triangle_counts[k, j] = 0
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
        x0 = x1 = x2 = x3 = y0 = y1 = z0 = z1 = triangles = 0
        previous = np.int64(codes[low])
        for i in range(low, high + 1):
            code = np.int64(codes[i])
            if i > low:
                if code == previous and (code == 0 or code == 15):
                    continue  # a uniform column next to an equal one: nothing is cut
                across = previous ^ code  # x edges of the four sample rows
                x0 += across & 1
                x1 += (across >> 1) & 1
                x2 += (across >> 2) & 1
                x3 += (across >> 3) & 1
                triangles += triangle_count[pair_case[previous | (code << 4)]]
            y0 += (code ^ (code >> 1)) & 1  # y edge of slice k
            y1 += ((code >> 2) ^ (code >> 3)) & 1  # y edge of slice k + 1
            z0 += (code ^ (code >> 2)) & 1  # z edge of sample row j
            z1 += ((code >> 1) ^ (code >> 3)) & 1  # z edge of sample row j + 1
            previous = code
        triangle_counts[k, j] = triangles
        edge_counts[k, j, 0] = x0
        edge_counts[k, j, 1] = y0
        edge_counts[k, j, 2] = z0
        if last_row:
            edge_counts[k, j + 1, 0] = x1
            edge_counts[k, j + 1, 2] = z1
        if top:
            edge_counts[k + 1, j, 0] = x2
            edge_counts[k + 1, j, 1] = y1
            if last_row:
                edge_counts[k + 1, j + 1, 0] = x3
    undefined |= _row_has_nan(volume[k, ny - 1])
    if k == nz - 2:
        for j in range(ny):
            undefined |= _row_has_nan(volume[k + 1, j])
    flags[k] = undefined


@njit(cache=True, nogil=True)
def _gradient(volume, k, j, i, spacing):
    """Central-difference gradient at sample (i, j, k) per mm (one-sided at the border), as (gx, gy, gz)."""
    nz, ny, nx = volume.shape
    low, high = max(i - 1, 0), min(i + 1, nx - 1)
    gx = (np.float64(volume[k, j, high]) - np.float64(volume[k, j, low])) / (spacing[0] * (high - low))
    low, high = max(j - 1, 0), min(j + 1, ny - 1)
    gy = (np.float64(volume[k, high, i]) - np.float64(volume[k, low, i])) / (spacing[1] * (high - low))
    low, high = max(k - 1, 0), min(k + 1, nz - 1)
    gz = (np.float64(volume[high, j, i]) - np.float64(volume[low, j, i])) / (spacing[2] * (high - low))
    return gx, gy, gz


@njit(cache=True, nogil=True, inline="always")
def _place_vertex(volume, iso, k, j, i, axis, vertex, spacing, origin, points, normals, on_sample):
    """Position (and, if ``normals`` is not empty, normal) of the vertex on the edge from sample (i, j, k) along
    ``axis``, interpolated linearly from that lower end; ``on_sample`` gets the flat index of the sample the vertex
    falls on exactly, else -1. Normals are the negated gradient interpolated along the edge, normalised (zero where
    the gradient vanishes)."""
    nz, ny, nx = volume.shape
    k1 = k + (axis == 2)
    j1 = j + (axis == 1)
    i1 = i + (axis == 0)
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
        ax, ay, az = _gradient(volume, k, j, i, spacing)
        bx, by, bz = _gradient(volume, k1, j1, i1, spacing)
        x = -(ax + t * (bx - ax))
        y = -(ay + t * (by - ay))
        z = -(az + t * (bz - az))
        length = np.sqrt(x * x + y * y + z * z)
        scale = 1.0 / length if length > 0.0 else 0.0
        normals[vertex, 0] = x * scale
        normals[vertex, 1] = y * scale
        normals[vertex, 2] = z * scale


@njit(cache=True, nogil=True)
def _fill_row(volume, threshold, iso, k, j, low, high, vertex_first, first_triangle, pair_case, triangle_table,
              triangle_count, spacing, origin, codes, ids, points, normals, on_sample, triangles):
    """Triangles of the row of cells ``(j, k)`` and the vertices of the edge rows it owns (columns low..high)."""
    nz, ny, nx = volume.shape
    last_row, top = _owned(j, k, ny, nz)
    a0 = volume[k, j]
    a1 = volume[k, j + 1]
    b0 = volume[k + 1, j]
    b1 = volume[k + 1, j + 1]
    for i in range(low, high + 1):
        codes[i] = (a0[i] >= threshold) + 2 * (a1[i] >= threshold) + 4 * (b0[i] >= threshold) + 8 * (
            b1[i] >= threshold)
    # Next vertex id of each edge row this row of cells touches: x edges of sample rows (j, k), (j + 1, k),
    # (j, k + 1), (j + 1, k + 1); y edges of slices k, k + 1; z edges of sample rows j, j + 1.
    nx0 = vertex_first[k, j, 0]
    nx1 = vertex_first[k, j + 1, 0]
    nx2 = vertex_first[k + 1, j, 0]
    nx3 = vertex_first[k + 1, j + 1, 0]
    ny0 = vertex_first[k, j, 1]
    ny1 = vertex_first[k + 1, j, 1]
    nz0 = vertex_first[k, j, 2]
    nz1 = vertex_first[k, j + 1, 2]
    row = first_triangle
    previous = np.int64(codes[low])
    for i in range(low, high + 1):
        code = np.int64(codes[i])
        if i > low:
            if code == previous and (code == 0 or code == 15):
                continue  # nothing cut here; the ids of uncut edges are never used
            across = previous ^ code
            # x edges from column i - 1 to i: slots 0-3 keep their ids for the cell (i - 1).
            if across & 1:
                ids[0] = nx0
                _place_vertex(volume, iso, k, j, i - 1, 0, nx0, spacing, origin, points, normals, on_sample)
                nx0 += 1
            if (across >> 1) & 1:
                ids[1] = nx1
                if last_row:
                    _place_vertex(volume, iso, k, j + 1, i - 1, 0, nx1, spacing, origin, points, normals, on_sample)
                nx1 += 1
            if (across >> 2) & 1:
                ids[2] = nx2
                if top:
                    _place_vertex(volume, iso, k + 1, j, i - 1, 0, nx2, spacing, origin, points, normals, on_sample)
                nx2 += 1
            if (across >> 3) & 1:
                ids[3] = nx3
                if last_row and top:
                    _place_vertex(volume, iso, k + 1, j + 1, i - 1, 0, nx3, spacing, origin, points, normals,
                                  on_sample)
                nx3 += 1
        # y and z edges at column i: slots 5, 7, 9, 11 for the cell (i - 1), moved to 4, 6, 8, 10 for cell i.
        if (code ^ (code >> 1)) & 1:
            ids[5] = ny0
            _place_vertex(volume, iso, k, j, i, 1, ny0, spacing, origin, points, normals, on_sample)
            ny0 += 1
        if ((code >> 2) ^ (code >> 3)) & 1:
            ids[7] = ny1
            if top:
                _place_vertex(volume, iso, k + 1, j, i, 1, ny1, spacing, origin, points, normals, on_sample)
            ny1 += 1
        if (code ^ (code >> 2)) & 1:
            ids[9] = nz0
            _place_vertex(volume, iso, k, j, i, 2, nz0, spacing, origin, points, normals, on_sample)
            nz0 += 1
        if ((code >> 1) ^ (code >> 3)) & 1:
            ids[11] = nz1
            if last_row:
                _place_vertex(volume, iso, k, j + 1, i, 2, nz1, spacing, origin, points, normals, on_sample)
            nz1 += 1
        if i > low:
            case = pair_case[previous | (code << 4)]
            for t in range(triangle_count[case]):
                triangles[row, 0] = ids[triangle_table[case, 3 * t]]
                triangles[row, 1] = ids[triangle_table[case, 3 * t + 1]]
                triangles[row, 2] = ids[triangle_table[case, 3 * t + 2]]
                row += 1
        ids[4] = ids[5]
        ids[6] = ids[7]
        ids[8] = ids[9]
        ids[10] = ids[11]
        previous = code


@njit(cache=True, nogil=True, parallel=True)
def fill_layers(volume, threshold, iso, bounds, parts, spans, vertex_first, triangle_first, pair_case,
                triangle_table, triangle_count, spacing, origin, points, normals, on_sample, triangles):
    """Triangles and owned vertices of the layers ``bounds[0]..bounds[-1]-1``, in slabs ``bounds[s]..bounds[s+1]-1``
    that ``parts`` threads take one at a time from a shared counter (module notes). Any split gives the same output.

    ``triangle_table`` holds id slots (:data:`TRIANGLES`); ``normals`` with zero rows skips the normals.
    """
    nz, ny, nx = volume.shape
    slabs = bounds.shape[0] - 1
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):
        codes = np.empty(nx, dtype=np.uint8)
        ids = np.zeros(12, dtype=np.int64)
        while True:
            slab = _take(queue, 1)
            if slab >= slabs:
                break
            for k in range(bounds[slab], bounds[slab + 1]):
                for j in range(ny - 1):
                    low = spans[k, j, 0]
                    high = spans[k, j, 1]
                    if low <= high:
                        _fill_row(volume, threshold, iso, k, j, low, high, vertex_first, triangle_first[k, j],
                                  pair_case, triangle_table, triangle_count, spacing, origin, codes, ids, points,
                                  normals, on_sample, triangles)


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
    if holes == 0:
        return points.shape[0], triangles.shape[0]
    new_id = np.arange(points.shape[0])
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
