"""Marching cubes with Paul Bourke's lookup tables, indexed and oriented like ``vtkMarchingCubes``.

Method (source 001, ``../shared/seeds/001_5825713f111ed41b.txt``, "Techniek 1: Marching cubes"): each cell of
the sample grid classifies its eight corners against the isovalue, looks its 8-bit case up in the triangle table
published by Paul Bourke (:mod:`algorithms._marching_cubes_tables`) and places the triangle vertices on the cut
edges by linear interpolation. Lorensen & Cline introduced the method (1987). Source 001 found generating the
mesh at full resolution slow, so ``step`` extracts a preview from every 2nd or 4th sample.

Conventions (those of ``vtkMarchingCubes``, which the tests compare against triangle by triangle)
-------------------------------------------------------------------------------------------------
- **Inside** is ``value >= isovalue`` (source 001: values above the chosen value are visible).
- **Vertices**: one per cut edge, interpolated from the edge's lower-index end, ``t = (iso - v0) / (v1 - v0)``.
  A vertex that falls exactly on a sample (``value == isovalue`` there) is shared by every cut edge meeting at
  that sample, and triangles that collapse to a line or point are dropped, as VTK's point locator does; so the
  mesh is indexed without two vertices for one point.
- **Orientation**: triangles are counter-clockwise seen from outside (from the lower values), so the right-hand
  normals ``(p1 - p0) x (p2 - p0)`` point outward and a closed surface has positive signed volume.
- **Normals** (optional): the negated central-difference gradient (one-sided at the volume border, in physical
  units, so anisotropic spacing is honoured), interpolated along the edge and normalised; they point outward.
- **Coordinates**: the volume frame, sample ``(i, j, k)`` at ``origin + spacing * (i, j, k)`` mm.

Bourke's table and VTK's case table (``vtkMarchingCubesTriangleCases``) triangulate 134 of the 254 non-empty
cases identically. They differ in the 120 cases in which a face of the cell has two diagonally opposite corners
inside and the other two outside: Bourke's table joins the inside corners across such a face, VTK's separates
them (our triangles there are VTK's for the complementary case, reversed). Each choice is made the same way for
both cells sharing the face, so both surfaces are closed. ``tests/algorithms/test_marching_cubes.py`` checks this
case by case and compares whole meshes triangle by triangle outside those cells.

Implementation (numba, parallel over k slices or over vertices; no Python loop per cell):

1. Classify every sample (an inside mask), note per row of cells the span of columns where anything happens,
   and count the cut edges of each slice and the triangles of each layer of cells (8-bit cases).
2. Prefix sums of the counts give every slice its first vertex id and every layer its first triangle.
3. Slabs of layers, balanced by work, run independently: each numbers the cut edges of its slices in a fixed
   order into small per-slice id planes (so each cut edge gets exactly one vertex, without hashing), records each
   vertex's edge, and writes its layers' triangles by looking the ids up.
4. Positions (and normals) are computed per vertex from its edge; vertices on the same sample are merged.

References
----------
W. E. Lorensen, H. E. Cline, "Marching cubes: a high resolution 3D surface construction algorithm", SIGGRAPH '87,
Computer Graphics 21(4), 163-169, 1987. doi:10.1145/37402.37422.
P. Bourke, "Polygonising a scalar field", 1994, http://paulbourke.net/geometry/polygonise/.
Source 001, section "Techniek 1: Marching cubes" (``../shared/seeds/001_5825713f111ed41b.txt``).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import numba
import numpy as np
from numba import njit, prange
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkCommand
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData

from . import _marching_cubes_tables as tables
from ._progress import OperationCancelled, ProgressCallback, report, scaled
from ._vtk import array_from_image, polydata_from_arrays, progress_for

__all__ = ["MarchingCubesMesh", "marching_cubes", "MarchingCubesFilter"]


# --------------------------------------------------------------------------------------------------------------
# Tables in the form the kernels use
# --------------------------------------------------------------------------------------------------------------
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


_PAIR_CASE = _column_pair_cases()
_EDGE_SLOTS = _edge_slots()
_TRIANGLES = tables.TRIANGLE_TABLE.astype(np.int64)
_TRIANGLE_COUNT = _triangle_counts()
_POPCOUNT4 = np.array([bin(v).count("1") for v in range(16)], dtype=np.int64)


# --------------------------------------------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------------------------------------------
# ``threshold`` is the isovalue in the volume's own number type such that ``value >= threshold`` exactly when
# ``value >= iso`` (see :func:`_inside_threshold`); comparing in the native type lets LLVM vectorise the scans.
# ``inside[k, j, i]`` is 1 where the sample is inside, 0 elsewhere: after the first pass only the vertex
# positions and normals read the volume, so the other kernels are compiled once, whatever its dtype.
# ``spans[k, j]`` is the inclusive range of sample columns ``i`` where anything happens in the row of cells
# ``(j, k)``: a column whose four samples are not all on one side, or that differs from its neighbour. Every cut
# edge of the four sample rows of that row of cells, and every cell with triangles, lies inside the span.


@njit(cache=True, nogil=True, parallel=True)
def _classify_layers(volume, threshold, start, stop, pair_case, triangle_count, popcount, inside, spans, counts):
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
        low = spans[span_layer, min(j, ny - 2), 0]
        high = spans[span_layer, min(j, ny - 2), 1]
        row_code = _edge_code(k, j, 0, 0)
        row = inside[k, j]
        for i in range(low, high):
            if row[i] != row[i + 1]:
                x_ids[j, i] = vertex
                if write:
                    vertex_edges[vertex] = row_code | (i << 2)
                vertex += 1
        if j + 1 < ny:
            next_row = inside[k, j + 1]
            for i in range(low, high + 1):
                if row[i] != next_row[i]:
                    y_ids[j, i] = vertex
                    if write:
                        vertex_edges[vertex] = row_code | (i << 2) | 1
                    vertex += 1
    return vertex


@njit(cache=True, nogil=True)
def _vertical_vertices(inside, k, first, spans, ids, vertex_edges):
    """Number the cut z edges between slices k and k + 1 from ``first`` and record their edges."""
    nz, ny, nx = inside.shape
    vertex = first
    for j in range(ny):
        low = spans[k, min(j, ny - 2), 0]
        high = spans[k, min(j, ny - 2), 1]
        row_code = _edge_code(k, j, 0, 2)
        lower = inside[k, j]
        upper = inside[k + 1, j]
        for i in range(low, high + 1):
            if lower[i] != upper[i]:
                ids[j, i] = vertex
                vertex_edges[vertex] = row_code | (i << 2)
                vertex += 1


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
def _fill_slabs(inside, bounds, vertex_first, planar_counts, triangle_first, spans, pair_case, triangle_table,
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
def _central_difference(volume, k, j, i, axis, step):
    """Derivative along ``axis`` at sample (i, j, k) per mm: central, one-sided at the volume border."""
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
    return (np.float64(b) - np.float64(a)) / (step * (high - low))


@njit(cache=True, nogil=True, parallel=True)
def _vertex_attributes(volume, iso, vertex_edges, spacing, origin, points, normals, on_sample):
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
def _merge_on_samples(points, normals, on_sample, triangles):
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


# --------------------------------------------------------------------------------------------------------------
# The core
# --------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MarchingCubesMesh:
    """An indexed triangle mesh in the volume frame.

    Attributes
    ----------
    points : ndarray, shape (n, 3), float32
        Vertex positions ``(x, y, z)`` in mm, volume frame (sample ``(i, j, k)`` at ``origin + spacing * (i, j, k)``).
    triangles : ndarray, shape (m, 3), int64
        Vertex indices of each triangle, counter-clockwise seen from outside (the lower values).
    normals : ndarray, shape (n, 3), float32, or None
        Unit outward normals from the negated, interpolated central-difference gradient; None unless requested.
        Zero where the gradient vanishes.
    values : ndarray, shape (n,), float32
        The isovalue whose surface each vertex belongs to (VTK's output scalars).
    """

    points: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None
    values: np.ndarray

    def to_polydata(self, scalars_name: str = "Isovalue") -> vtkPolyData:
        """The mesh as ``vtkPolyData``: triangles as polys, ``values`` as point scalars, normals if present."""
        polydata = polydata_from_arrays(self.points, self.triangles)
        values = numpy_support.numpy_to_vtk(np.ascontiguousarray(self.values), deep=True)
        values.SetName(scalars_name)
        polydata.GetPointData().SetScalars(values)
        if self.normals is not None:
            normals = numpy_support.numpy_to_vtk(np.ascontiguousarray(self.normals), deep=True)
            normals.SetName("Normals")
            polydata.GetPointData().SetNormals(normals)
        return polydata


def _validated_volume(volume) -> np.ndarray:
    array = np.asarray(volume)
    if array.ndim != 3:
        raise ValueError(f"marching cubes needs a 3D array (nz, ny, nx), got shape {array.shape}")
    if array.dtype == np.bool_:
        array = array.view(np.uint8)
    elif array.dtype.kind not in "iuf":
        raise ValueError(f"marching cubes needs real scalar values, got dtype {array.dtype}")
    elif array.dtype == np.float16:
        array = array.astype(np.float32)
    return np.ascontiguousarray(array, dtype=array.dtype.newbyteorder("="))


def _validated_levels(level) -> np.ndarray:
    levels = np.atleast_1d(np.asarray(level, dtype=np.float64))
    if levels.ndim != 1 or levels.size == 0:
        raise ValueError(f"give one isovalue or a sequence of isovalues, got {level!r}")
    if not np.all(np.isfinite(levels)):
        raise ValueError(f"isovalues must be finite numbers, got {levels.tolist()}")
    if np.unique(levels).size != levels.size:
        raise ValueError(f"isovalues must be distinct, got {levels.tolist()}")
    return levels


def _validated_triple(values, name: str, *, positive: bool = False) -> np.ndarray:
    try:
        triple = np.asarray(values, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers (x, y, z) in mm, got {values!r}") from None
    if not np.all(np.isfinite(triple)) or (positive and np.any(triple <= 0)):
        kind = "positive" if positive else "finite"
        raise ValueError(f"{name} must be three {kind} numbers (x, y, z) in mm, got {values!r}")
    return triple


def _slab_bounds(counts: np.ndarray, plane_size: int, pieces: int) -> np.ndarray:
    """Layer boundaries splitting the fill work into ``pieces`` slabs of about equal cost."""
    layers = counts.shape[0] - 1
    # Vertices and triangles dominate; every layer also scans its cells and a slice of samples.
    work = counts[:-1, 0] + counts[:-1, 1] + 2 * counts[:-1, 2] + plane_size // 4 + 1
    cumulative = np.cumsum(work)
    targets = cumulative[-1] * np.arange(1, pieces) / pieces
    inner = np.minimum(np.searchsorted(cumulative, targets) + 1, layers)
    return np.concatenate(([0], inner, [layers])).astype(np.int64)


def _inside_threshold(dtype: np.dtype, iso: float):
    """The isovalue in the volume's number type: ``value >= threshold`` exactly when ``float(value) >= iso``.

    None when no value of the type can be on both sides (an integer type whose range lies on one side).
    """
    if dtype.kind in "iu":
        limits = np.iinfo(dtype)
        threshold = np.ceil(iso)
        return dtype.type(threshold) if limits.min < threshold <= limits.max else None
    if dtype == np.float32:
        threshold = np.float32(iso)
        if np.float64(threshold) < iso:
            threshold = np.nextafter(threshold, np.float32(np.inf))
        return threshold
    return np.float64(iso)


#: Below this many samples the kernels run on one thread: the work takes a few milliseconds, less than waking
#: a second thread can cost when the other core is busy (measured: 8 ms per parallel region under load).
PARALLEL_MIN_SAMPLES = 2_000_000


@contextmanager
def _numba_threads(count: int):
    """Run numba's parallel kernels on ``count`` threads inside the block (numba's setting is per thread)."""
    previous = numba.get_num_threads()
    numba.set_num_threads(count)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def _extract(array, iso, spacing, origin, with_normals, inside, spans, progress):
    """One isosurface of ``array``: points, normals (or None), triangles."""
    nz, ny, nx = array.shape
    threshold = _inside_threshold(array.dtype, iso)
    if threshold is None:
        report(progress, 1.0)
        return np.empty((0, 3), np.float32), np.empty((0, 3), np.float32) if with_normals else None, np.empty(
            (0, 3), np.int64)
    threads = numba.get_num_threads()
    rounds = int(np.clip(array.size // 8_000_000, 1, 8))  # calls between which progress is reported
    counts = np.zeros((nz, 4), dtype=np.int64)
    chunks = np.linspace(0, nz - 1, rounds + 1).astype(np.int64)
    for n in range(rounds):
        _classify_layers(array, threshold, chunks[n], chunks[n + 1], _PAIR_CASE, _TRIANGLE_COUNT, _POPCOUNT4, inside,
                         spans, counts)
        report(progress, 0.3 * (n + 1) / rounds)
    if counts[:, 3].any():
        raise ValueError("the volume contains NaN values; marching cubes needs a value at every sample")

    planar_counts = np.ascontiguousarray(counts[:, 0])
    vertex_first = np.concatenate(([0], np.cumsum(planar_counts + counts[:, 1])))
    triangle_first = np.concatenate(([0], np.cumsum(counts[:, 2])))
    vertex_edges = np.empty(vertex_first[-1], dtype=np.int64)
    triangles = np.empty((triangle_first[-1], 3), dtype=np.int64)
    if triangles.shape[0]:
        bounds = _slab_bounds(counts, ny * nx, threads * rounds)
        for n in range(rounds):
            _fill_slabs(inside, bounds[n * threads:(n + 1) * threads + 1], vertex_first, planar_counts, triangle_first,
                        spans, _PAIR_CASE, _TRIANGLES, _TRIANGLE_COUNT, _EDGE_SLOTS, vertex_edges, triangles)
            report(progress, 0.3 + 0.5 * (n + 1) / rounds)
    points = np.empty((vertex_edges.shape[0], 3), dtype=np.float32)
    normals = np.empty((vertex_edges.shape[0] if with_normals else 0, 3), dtype=np.float32)
    on_sample = np.empty(vertex_edges.shape[0], dtype=np.int64)
    _vertex_attributes(array, iso, vertex_edges, spacing, origin, points, normals, on_sample)
    report(progress, 0.95)
    n_points, n_triangles = _merge_on_samples(points, normals, on_sample, triangles)
    report(progress, 1.0)
    return points[:n_points], normals[:n_points] if with_normals else None, triangles[:n_triangles]


def marching_cubes(
    volume,
    level,
    *,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
    step: int = 1,
    normals: bool = False,
    progress: ProgressCallback = None,
) -> MarchingCubesMesh:
    """Isosurface(s) of a sampled scalar field by marching cubes with Paul Bourke's tables.

    Parameters
    ----------
    volume : ndarray, shape (nz, ny, nx)
        Scalar samples indexed ``[k, j, i]`` (any real dtype; bool is read as 0/1). At least 2 samples per axis
        (after ``step``); NaN is not allowed.
    level : float or sequence of float
        Isovalue(s), distinct. Inside is ``value >= level``. Several values give several surfaces in one mesh,
        like ``vtkMarchingCubes.SetValue(i, v)``; ``values`` tells them apart.
    spacing : (sx, sy, sz)
        Sample spacing in mm along i, j, k.
    origin : (x, y, z)
        Position in mm of sample (0, 0, 0).
    step : int
        Use every ``step``-th sample along each axis (2 or 4 for a fast preview while the isovalue is dragged).
        The samples kept are ``0, step, 2 step, ...``, so up to ``step - 1`` samples at the far end of an axis are
        left out.
    normals : bool
        Also compute unit outward normals from central-difference gradients.
    progress : callable, optional
        Called with the fraction done between passes; may raise :class:`~algorithms._progress.OperationCancelled`.

    Returns
    -------
    MarchingCubesMesh
        Points ``(n, 3)`` float32 in mm in the volume frame, triangles ``(m, 3)`` int64 counter-clockwise seen
        from outside, optional normals ``(n, 3)`` float32, and the isovalue of each point.

    Raises
    ------
    ValueError
        If the volume is not 3D, has a non-real dtype, has fewer than 2 samples on an axis (after ``step``) or more
        than 65536 along i or j, or holds NaN; if no isovalue is given or they are not finite and distinct; if
        spacing or origin are not three finite numbers (spacing positive); if ``step`` is not a positive integer.

    Notes
    -----
    Each cell's case sets bit ``c`` when corner ``c`` is below the isovalue (Bourke's convention), and the
    triangles come from :data:`algorithms._marching_cubes_tables.TRIANGLE_TABLE` unchanged: with Bourke's corner
    numbering laid on the grid as VTK lays its own, his triangles are already counter-clockwise seen from the
    outside, VTK's winding. Cases without an ambiguous face (two diagonally opposite corners inside and the other
    two outside) are triangulated exactly like ``vtkMarchingCubes``. On an ambiguous face Bourke's table joins the
    inside corners (the surface passes between the outside ones) where VTK's separates them; in those 120 cases
    our triangles are VTK's for the complementary case with reversed winding. Both choices are consistent between
    neighbouring cells, so the surface is closed wherever it does not meet the volume border.

    Each cut edge gets exactly one vertex; vertices that fall exactly on a sample are merged (see the module
    docstring), so a surface through samples equal to the isovalue can have pinched (non-manifold) vertices, as
    VTK's output has.

    References
    ----------
    Source 001, "Techniek 1: Marching cubes" (``../shared/seeds/001_5825713f111ed41b.txt``).
    W. E. Lorensen, H. E. Cline, SIGGRAPH '87, doi:10.1145/37402.37422. P. Bourke, "Polygonising a scalar field",
    http://paulbourke.net/geometry/polygonise/.

    Examples
    --------
    >>> from app.datasets import sphere_field
    >>> mesh = marching_cubes(sphere_field((32, 32, 32), 10.0), 0.0, normals=True)
    >>> mesh.points.shape[1], mesh.triangles.shape[1]
    (3, 3)
    """
    array = _validated_volume(volume)
    levels = _validated_levels(level)
    spacing = _validated_triple(spacing, "spacing", positive=True)
    origin = _validated_triple(origin, "origin")
    if isinstance(step, (bool, np.bool_)) or not isinstance(step, (int, np.integer)) or step < 1:
        raise ValueError(f"step must be a positive integer (1 for full resolution, 2 or 4 for a preview), got {step!r}")
    if step > 1:
        array = np.ascontiguousarray(array[::step, ::step, ::step])
        spacing = spacing * step
    if min(array.shape) < 2:
        raise ValueError(
            f"marching cubes needs at least 2 samples along each axis, got (nz, ny, nx) = {array.shape}"
            + (f" after step {step}" if step > 1 else "")
        )
    if max(array.shape[1:]) > 65536:
        raise ValueError(f"marching cubes handles at most 65536 samples along i and j, got (ny, nx) = {array.shape[1:]}")

    inside = np.empty(array.shape, dtype=np.uint8)  # work arrays shared by all isovalues
    spans = np.empty((array.shape[0] - 1, array.shape[1] - 1, 2), dtype=np.int64)
    parts = []
    with _numba_threads(numba.get_num_threads() if array.size >= PARALLEL_MIN_SAMPLES else 1):
        for n, iso in enumerate(levels):
            parts.append(_extract(array, iso, spacing, origin, normals, inside, spans,
                                  scaled(progress, n / levels.size, (n + 1) / levels.size)))
    sizes = [part[0].shape[0] for part in parts]
    values = np.repeat(levels.astype(np.float32), sizes)
    if len(parts) == 1:
        points, normals_array, triangles = parts[0]
        return MarchingCubesMesh(points, triangles, normals_array, values)
    offsets = np.cumsum([0] + sizes[:-1])
    return MarchingCubesMesh(
        points=np.concatenate([part[0] for part in parts]),
        triangles=np.concatenate([part[2] + offset for part, offset in zip(parts, offsets)]),
        normals=np.concatenate([part[1] for part in parts]) if normals else None,
        values=values,
    )


# --------------------------------------------------------------------------------------------------------------
# VTK filter
# --------------------------------------------------------------------------------------------------------------
class MarchingCubesFilter(VTKPythonAlgorithmBase):
    """``vtkImageData`` -> ``vtkPolyData`` isosurfaces by :func:`marching_cubes`, with ``vtkMarchingCubes``' API.

    Contour values are set with ``SetValue(i, value)`` / ``SetNumberOfContours(n)`` (new values start at 0.0, as
    in ``vtkContourValues``) and must be distinct; ``ComputeNormals`` is on by default, as in VTK. ``SetStep``
    extracts a preview from every ``step``-th sample. The input's active point scalars are contoured; the output
    is placed like VTK's: index ``(i, j, k)`` of the input extent at ``origin + direction @ (spacing * index)``.
    Output point data: the isovalue of each point as scalars (named after the input array) and, if computed,
    ``Normals``.

    Examples
    --------
    >>> from algorithms._vtk import image_from_array, run_algorithm
    >>> contour = MarchingCubesFilter()
    >>> contour.SetInputDataObject(image_from_array(volume, spacing, origin))
    >>> contour.SetValue(0, 300.0)
    >>> polydata = run_algorithm(contour)
    """

    def __init__(self) -> None:
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkPolyData")
        self._values: list[float] = [0.0]
        self._compute_normals = True
        self._step = 1

    def SetValue(self, index: int, value: float) -> None:  # noqa: N802 - VTK naming
        index, value = int(index), float(value)
        if index < 0:
            raise ValueError(f"contour index must be 0 or more, got {index}")
        values = self._values + [0.0] * (index + 1 - len(self._values))
        values[index] = value
        if values != self._values:
            self._values = values
            self.Modified()

    def GetValue(self, index: int) -> float:  # noqa: N802
        return self._values[int(index)]

    def GetValues(self) -> tuple[float, ...]:  # noqa: N802
        return tuple(self._values)

    def SetNumberOfContours(self, count: int) -> None:  # noqa: N802
        count = int(count)
        if count < 0:
            raise ValueError(f"the number of contours must be 0 or more, got {count}")
        values = (self._values + [0.0] * count)[:count]
        if values != self._values:
            self._values = values
            self.Modified()

    def GetNumberOfContours(self) -> int:  # noqa: N802
        return len(self._values)

    def SetComputeNormals(self, flag: bool) -> None:  # noqa: N802
        flag = bool(flag)
        if flag != self._compute_normals:
            self._compute_normals = flag
            self.Modified()

    def GetComputeNormals(self) -> bool:  # noqa: N802
        return self._compute_normals

    def ComputeNormalsOn(self) -> None:  # noqa: N802
        self.SetComputeNormals(True)

    def ComputeNormalsOff(self) -> None:  # noqa: N802
        self.SetComputeNormals(False)

    def SetStep(self, step: int) -> None:  # noqa: N802
        if isinstance(step, bool) or int(step) != step or step < 1:
            raise ValueError(f"step must be a positive integer, got {step!r}")
        if int(step) != self._step:
            self._step = int(step)
            self.Modified()

    def GetStep(self) -> int:  # noqa: N802
        return self._step

    def RequestData(self, request, in_info, out_info):  # noqa: N802
        image = vtkImageData.GetData(in_info[0], 0)
        output = vtkPolyData.GetData(out_info, 0)
        if not self._values:
            return 1
        spacing = np.array(image.GetSpacing())
        first_index = np.array(image.GetExtent()[::2], dtype=np.float64)
        direction = np.array([image.GetDirectionMatrix().GetElement(r, c) for r in range(3) for c in range(3)])
        direction = direction.reshape(3, 3)
        try:
            mesh = marching_cubes(
                array_from_image(image),
                self._values,
                spacing=spacing,
                origin=spacing * first_index,
                step=self._step,
                normals=self._compute_normals,
                progress=progress_for(self),
            )
        except OperationCancelled:
            return 1  # VTK's convention: an aborted filter returns an empty output
        except ValueError as error:
            self.InvokeEvent(vtkCommand.ErrorEvent, str(error))
            return 0
        if not np.allclose(direction, np.eye(3)):
            mesh = MarchingCubesMesh(
                points=(mesh.points @ direction.T).astype(np.float32),
                triangles=mesh.triangles,
                normals=None if mesh.normals is None else (mesh.normals @ direction.T).astype(np.float32),
                values=mesh.values,
            )
        name = image.GetPointData().GetScalars().GetName() or "Isovalue"
        result = mesh.to_polydata(scalars_name=name)
        points = numpy_support.vtk_to_numpy(result.GetPoints().GetData())
        points += np.asarray(image.GetOrigin(), dtype=points.dtype)
        output.ShallowCopy(result)
        return 1
