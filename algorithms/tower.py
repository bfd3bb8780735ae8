"""Voxel surfaces as triangle strips: the tower algorithm of source 000 and its hybrid variant.

Method
------
The tower algorithm draws exactly the faces of :func:`algorithms.voxel_faces.voxel_faces` (every face of a solid
voxel whose neighbour is empty or outside the volume), but as triangle strips: no indices, fewer vertices. It
walks the model slice by slice along the height axis ``k`` (z):

1. **Circumferences.** In slice ``k``, every boundary loop of every cluster of solid voxels (4-connected in the
   slice: the outer boundary and each hole) becomes one strip that wraps the side walls of that layer. Walking
   the loop, the strip takes the bottom and the top vertex of each vertical edge in turn (``b0, t0, b1, t1, ...``)
   and closes by repeating ``b0, t0``; a loop of ``m`` faces gives ``2(m + 1)`` vertices and ``2m`` triangles.
2. **Discrepancies.** Rows (along ``i``, one per ``j``) where slice ``k`` differs from slice ``k - 1`` hold
   exposed top faces of the lower slice or bottom faces of the upper one. The first slice is compared with the
   empty space below it and the last with the empty space above it, which marks every row that holds voxels.
3. **Sides.** On each marked row, every maximal run of ``n`` exposed top (or bottom) faces becomes one strip of
   ``2(n + 1)`` vertices.

Loops are traced with a successor rule on directed boundary edges (solid on the right seen from ``+z``): at a
corner, the next edge is the first boundary edge found turning right, going straight, turning left. At a pinch
point (two solid voxels touching only diagonally) turning right keeps hugging the same voxel, so the clusters
stay 4-connected; since every boundary edge has exactly one successor and one predecessor, the loops partition
the side faces and every side face is drawn exactly once.

Orientation under the strip convention
--------------------------------------
In a strip, triangle ``t`` is ``(v_t, v_t+1, v_t+2)`` for even ``t`` and ``(v_t+1, v_t, v_t+2)`` for odd ``t``
(VTK's and OpenGL's rule; Direct3D flips the culling direction per triangle to the same effect). So the winding
of a whole strip is fixed by its first triangle. Circumference loops run with the solid on the right seen from
above, which makes ``(b0, t0, b1)`` face outward. A top run is written ``(x0, y+), (x0, y-), (x1, y+), ...`` and
a bottom run with every pair swapped, ``(x0, y-), (x0, y+), ...``. Reversing a whole strip of an even number of
vertices, which is one reading of the source's "reversed order" for bottom faces, would *not* flip its faces: its
first triangle is the old last (odd) triangle read backwards, with the same winding.

Each quad is split along the same diagonal as in :func:`algorithms.voxel_faces.voxel_faces`, so both
representations rasterise every face as the same two triangles.

Hybrid (source 000, section 6.3): after the tower pass, strips of at most ``L`` vertices (the source used 10) are
turned back into indexed triangles exactly as the baseline stores faces (4 vertices and 6 indices per face, the
same diagonal), to save the cost of many tiny draw calls; longer strips stay strips.

Axis order: the volume array is ``(nz, ny, nx)``, indexed ``[k, j, i]``; spacing and origin are ``(x, y, z)`` =
``(i, j, k)``. A face corner is at ``origin + spacing * ((i, j, k) +- 0.5)`` in the volume frame (mm).

References
----------
Source 000 (``../shared/seeds/000_d719b521960fa927.txt``): section 3 (triangle strips and culling), section 6
(the tower algorithm, algorithms 2 and 3; linear, about 5N steps, section 6.2), section 6.3 (hybrid) and
section 7 (equivalence with the baseline).
F. Evans, S. Skiena, A. Varshney, "Optimizing triangle strips for fast rendering", Proc. IEEE Visualization '96,
doi:10.1109/VISUAL.1996.568125 (stripping general meshes, the problem VTK's vtkStripper solves greedily).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ._progress import ProgressCallback, report, scaled
from ._vtk import cell_array_from_offsets
from .voxel_faces import VoxelSurfaceFilter, checked_volume, face_triangles, validated_geometry

#: Codes of :attr:`TriangleStrips.kinds`.
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
_CHUNK_VOXELS = 8_000_000


@dataclass(frozen=True)
class TriangleStrips:
    """A voxel surface as triangle strips whose vertices are stored in strip order (no indices).

    Attributes
    ----------
    points : ndarray, shape (V, 3), float32
        Strip vertices (mm, volume frame); strip ``s`` is ``points[offsets[s]:offsets[s + 1]]``.
    offsets : ndarray, shape (S + 1,), int64
        CSR offsets of the ``S`` strips into ``points``.
    kinds : ndarray, shape (S,), int8
        :data:`STRIP_CIRCUMFERENCE`, :data:`STRIP_TOP` or :data:`STRIP_BOTTOM` for each strip.
    spacing, origin : tuple of float
        The voxel size and the position of voxel ``(0, 0, 0)``'s centre (mm, ``(x, y, z)`` order) used.
    """

    points: np.ndarray
    offsets: np.ndarray
    kinds: np.ndarray
    spacing: tuple[float, float, float]
    origin: tuple[float, float, float]

    @property
    def n_strips(self) -> int:
        return len(self.offsets) - 1

    @property
    def n_vertices(self) -> int:
        return len(self.points)

    @property
    def n_triangles(self) -> int:
        return self.n_vertices - 2 * self.n_strips

    @property
    def lengths(self) -> np.ndarray:
        """Vertices per strip, shape ``(S,)``."""
        return np.diff(self.offsets)

    def to_polydata(self) -> vtkPolyData:
        """The strips as a ``vtkPolyData`` with ``SetStrips`` (point ids ``0 .. V-1`` in order; deep copies)."""
        polydata = vtkPolyData()
        polydata.SetPoints(_vtk_points(self.points))
        polydata.SetStrips(cell_array_from_offsets(self.offsets, np.arange(self.n_vertices, dtype=np.int64)))
        return polydata


@dataclass(frozen=True)
class HybridSurface:
    """A voxel surface as indexed triangles (the short strips, stored like the baseline) plus the long strips.

    Attributes
    ----------
    points : ndarray, shape (4F, 3), float32
        Corners of the ``F`` faces converted from short strips, four per face, counter-clockwise from outside.
    triangles : ndarray, shape (2F, 3), int32 (int64 beyond 2**31 points)
        ``(4f, 4f+1, 4f+2)`` and ``(4f, 4f+2, 4f+3)`` for face ``f``, as in the baseline.
    strips : TriangleStrips
        The strips longer than ``max_strip_vertices``, unchanged.
    max_strip_vertices : int
        ``L``: strips with at most this many vertices were converted.
    """

    points: np.ndarray
    triangles: np.ndarray
    strips: TriangleStrips
    max_strip_vertices: int

    @property
    def n_triangles(self) -> int:
        return len(self.triangles) + self.strips.n_triangles

    def to_polydata(self) -> vtkPolyData:
        """Triangles (``SetPolys``) and strips (``SetStrips``) over one point list: triangle points first."""
        polydata = vtkPolyData()
        polydata.SetPoints(_vtk_points(np.concatenate([self.points, self.strips.points])))
        n_triangles = len(self.triangles)
        polydata.SetPolys(
            cell_array_from_offsets(np.arange(0, 3 * n_triangles + 1, 3, dtype=np.int64), self.triangles.ravel())
        )
        strip_ids = np.arange(len(self.points), len(self.points) + self.strips.n_vertices, dtype=np.int64)
        polydata.SetStrips(cell_array_from_offsets(self.strips.offsets, strip_ids))
        return polydata


def _vtk_points(points: np.ndarray) -> vtkPoints:
    vtk_points = vtkPoints()
    vtk_points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float32), deep=True))
    return vtk_points


def tower_strips(
    volume,
    *,
    threshold=None,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
    progress: ProgressCallback = None,
) -> TriangleStrips:
    """The visible voxel faces as triangle strips by the tower algorithm (source 000, section 6).

    Parameters
    ----------
    volume : ndarray, shape (nz, ny, nx)
        A boolean mask (True = solid) or a scalar volume, indexed ``[k, j, i]``; ``k`` is the height axis along
        which the slices are walked.
    threshold : float, optional
        For a scalar volume: voxels with ``value >= threshold`` are solid. Must be omitted for a boolean mask.
    spacing : (sx, sy, sz)
        Voxel size in mm along ``i``, ``j``, ``k``.
    origin : (x, y, z)
        Position in mm of the centre of voxel ``(0, 0, 0)``.
    progress : callable, optional
        Called with the fraction done between chunks of slices; may raise ``OperationCancelled``.

    Returns
    -------
    TriangleStrips
        For each slice ``k`` in turn: its circumference strips (one per boundary loop), then the top strips of
        slice ``k - 1`` and bottom strips of slice ``k`` on the rows where the two differ; the top strips of the
        last slice come last. Every strip has an even number of vertices; together they draw each visible face
        exactly once, as two outward-facing triangles.

    Raises
    ------
    ValueError
        See :func:`algorithms.voxel_faces.checked_volume` and :func:`algorithms.voxel_faces.validated_geometry`.

    Notes
    -----
    Time and memory are linear in the number of voxels. Slices are independent and run in parallel (numba): a
    counting pass gives each slice's exact output size, and a second pass writes every slice into its own range
    of the output. Vertex positions are computed exactly as the baseline computes them (float64, stored as
    float32), so both representations hold bit-identical corners.

    References
    ----------
    Source 000, ``../shared/seeds/000_d719b521960fa927.txt``, sections 6 (algorithms 2 and 3) and 7.

    Examples
    --------
    >>> import numpy as np
    >>> strips = tower_strips(np.ones((1, 1, 1), dtype=bool))
    >>> strips.n_strips, strips.n_vertices, strips.n_triangles   # one loop of 4 walls, one top, one bottom
    (3, 18, 12)
    """
    array, threshold = checked_volume(volume, threshold)
    spacing_t, origin_t = validated_geometry(spacing, origin)
    geometry = origin_t + spacing_t  # (ox, oy, oz, sx, sy, sz), a tuple of floats for numba
    nz, ny, nx = array.shape
    # One empty voxel of padding on every side: voxel (i, j, k) is solid[k + 1, j + 1, i + 1], and the kernels
    # read the neighbours of border voxels (outside = empty) without bounds checks.
    solid = np.zeros((nz + 2, ny + 2, nx + 2), dtype=np.bool_)
    inner = solid[1:-1, 1:-1, 1:-1]
    if threshold is None:
        inner[...] = array
    else:
        np.greater_equal(array, threshold, out=inner)
    n_units = nz + 1  # unit k: the circumferences of slice k (k < nz) and the interface below slice k

    # Pass 1 counts what every unit emits; pass 2 walks again and writes each unit into its own exact range, so
    # slices run in parallel without a buffer to compact.
    vertex_count = np.zeros(n_units, dtype=np.int64)
    strip_count = np.zeros(n_units, dtype=np.int64)
    no_points, no_lengths, no_kinds = np.empty((0, 3), np.float32), np.empty(0, np.int64), np.empty(0, np.int8)
    _walk(solid, geometry, no_points, no_lengths, no_kinds, vertex_count, strip_count, False, scaled(progress, 0, 0.4))
    vertex_start = np.zeros(n_units + 1, dtype=np.int64)
    strip_start = np.zeros(n_units + 1, dtype=np.int64)
    np.cumsum(vertex_count, out=vertex_start[1:])
    np.cumsum(strip_count, out=strip_start[1:])
    points = np.empty((vertex_start[-1], 3), dtype=np.float32)
    lengths = np.empty(strip_start[-1], dtype=np.int64)
    kinds = np.empty(strip_start[-1], dtype=np.int8)
    _walk(solid, geometry, points, lengths, kinds, vertex_start, strip_start, True, scaled(progress, 0.4, 1.0))

    offsets = np.zeros(len(lengths) + 1, dtype=np.int64)
    np.cumsum(lengths, out=offsets[1:])
    return TriangleStrips(points=points, offsets=offsets, kinds=kinds, spacing=spacing_t, origin=origin_t)


def _walk(solid, geometry, points, lengths, kinds, vertex_slots, strip_slots, write, progress) -> None:
    """Run every unit, in chunks with progress between them (see :func:`_walk_units`)."""
    n_units = solid.shape[0] - 1
    # Chunks of about _CHUNK_VOXELS voxels: few parallel launches (each ends at a barrier of all threads), yet
    # progress several times a second on large volumes.
    chunk = max(1, -(-_CHUNK_VOXELS // (solid.shape[1] * solid.shape[2])))
    for first in range(0, n_units, chunk):
        last = min(n_units, first + chunk)
        _walk_units(solid, geometry, first, last, points, lengths, kinds, vertex_slots, strip_slots, write)
        report(progress, last / n_units)


def hybrid(
    strips_or_volume,
    *,
    max_strip_vertices: int = 10,
    threshold=None,
    spacing=None,
    origin=None,
    progress: ProgressCallback = None,
) -> HybridSurface:
    """The hybrid of source 000 (section 6.3): short strips back to indexed triangles, long strips kept.

    Parameters
    ----------
    strips_or_volume : TriangleStrips or ndarray, shape (nz, ny, nx)
        Strips from :func:`tower_strips`, or a voxel model to run :func:`tower_strips` on first.
    max_strip_vertices : int
        ``L``: strips with at most ``L`` vertices become indexed triangles (the source used 10). 0 keeps every
        strip; a value at least the longest strip converts everything.
    threshold, spacing, origin :
        Passed to :func:`tower_strips` when a volume is given (spacing and origin default to 1 mm and 0);
        must be omitted when strips are given.
    progress : callable, optional
        Progress of the tower pass when a volume is given.

    Returns
    -------
    HybridSurface
        Converted faces as 4 vertices ``(4F, 3)`` and two triangles ``(2F, 3)`` each, wound and split exactly as
        the strip drew them, plus the remaining strips.

    Raises
    ------
    ValueError
        If ``max_strip_vertices`` is not a non-negative integer, if strips are given together with threshold,
        spacing or origin, or if a strip is not a tower strip (an even number of vertices, at least 4), plus the
        errors of :func:`tower_strips` for a volume.

    Notes
    -----
    A tower strip of ``2(n + 1)`` vertices is ``n`` quads: vertices ``v2q .. v2q+3`` for quad ``q``, drawn as
    ``(v2q, v2q+1, v2q+2)`` and ``(v2q+2, v2q+1, v2q+3)``. Stored as ``(v2q+1, v2q+3, v2q+2, v2q)`` with triangles
    ``(0, 1, 2), (0, 2, 3)``, the quad is the baseline's counter-clockwise corner order with the same triangles.

    References
    ----------
    Source 000, ``../shared/seeds/000_d719b521960fa927.txt``, sections 6.3 and 9.3.
    """
    if isinstance(max_strip_vertices, (bool, np.bool_)) or not isinstance(max_strip_vertices, (int, np.integer)):
        raise ValueError(f"max_strip_vertices must be an integer, got {max_strip_vertices!r}")
    if max_strip_vertices < 0:
        raise ValueError(f"max_strip_vertices must be >= 0, got {max_strip_vertices}")
    if isinstance(strips_or_volume, TriangleStrips):
        if threshold is not None or spacing is not None or origin is not None:
            raise ValueError("threshold, spacing and origin apply to a volume; the strips already carry their geometry")
        strips = strips_or_volume
    else:
        strips = tower_strips(
            strips_or_volume,
            threshold=threshold,
            spacing=(1.0, 1.0, 1.0) if spacing is None else spacing,
            origin=(0.0, 0.0, 0.0) if origin is None else origin,
            progress=progress,
        )

    lengths = strips.lengths
    if np.any(lengths % 2) or np.any(lengths < 4):
        raise ValueError("hybrid expects tower strips: every strip needs an even number of vertices, at least 4")
    short = lengths <= max_strip_vertices

    # Quads of the short strips: quad q of strip s starts at vertex offsets[s] + 2q.
    quads_per_strip = (lengths[short] - 2) // 2
    strip_first = strips.offsets[:-1][short]
    quad_start = np.repeat(strip_first, quads_per_strip) + 2 * _ranks(quads_per_strip)
    corners = np.take(strips.points, quad_start[:, None] + np.array([1, 3, 2, 0]), axis=0)  # (F, 4, 3)
    triangles = face_triangles(len(quad_start))

    kept_vertices = np.repeat(~short, lengths)
    kept_lengths = lengths[~short]
    kept_offsets = np.zeros(len(kept_lengths) + 1, dtype=np.int64)
    np.cumsum(kept_lengths, out=kept_offsets[1:])
    long_strips = TriangleStrips(
        points=np.compress(kept_vertices, strips.points, axis=0),
        offsets=kept_offsets,
        kinds=strips.kinds[~short],
        spacing=strips.spacing,
        origin=strips.origin,
    )
    return HybridSurface(
        points=corners.reshape(-1, 3),
        triangles=triangles,
        strips=long_strips,
        max_strip_vertices=int(max_strip_vertices),
    )


def _ranks(counts: np.ndarray) -> np.ndarray:
    """``[0, 1, .., counts[0]-1, 0, 1, .., counts[1]-1, ...]`` (position within each group)."""
    total = int(counts.sum())
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    return np.arange(total, dtype=np.int64) - starts


# ----------------------------------------------------------------------------------------------------------------
# numba kernels
# ----------------------------------------------------------------------------------------------------------------
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
def _run_strip(points, v, geometry, first_i, end_i, j, k, top, write):
    """Emit the strip of faces ``first_i .. end_i - 1`` of row ``j`` between slices k-1 and k; returns next ``v``."""
    ox, oy, oz, sx, sy, sz = geometry
    z = oz + sz * (k - 0.5)
    y_low = oy + sy * (j - 0.5)
    y_high = oy + sy * (j + 0.5)
    for c in range(first_i, end_i + 1):
        x = ox + sx * (c - 0.5)
        if top:  # (x, y+), (x, y-): the first triangle faces +z
            v = _put_pair(points, v, x, y_high, z, x, y_low, z, write)
        else:  # pairs swapped: the first triangle faces -z
            v = _put_pair(points, v, x, y_low, z, x, y_high, z, write)
    return v


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
        top_first = -1
        bottom_first = -1
        for i in range(nx + 1):
            below = _at(solid, k - 1, j, i)  # i == nx reads the empty padding and ends every run
            above = _at(solid, k, j, i)
            top = below and not above
            bottom = above and not below
            if top and top_first < 0:
                top_first = i
            elif not top and top_first >= 0:
                first = v
                v = _run_strip(points, v, geometry, top_first, i, j, k, True, write)
                s = _end_strip(lengths, kinds, s, v - first, STRIP_TOP, write)
                top_first = -1
            if bottom and bottom_first < 0:
                bottom_first = i
            elif not bottom and bottom_first >= 0:
                first = v
                v = _run_strip(points, v, geometry, bottom_first, i, j, k, False, write)
                s = _end_strip(lengths, kinds, s, v - first, STRIP_BOTTOM, write)
                bottom_first = -1
    return v, s


@njit(cache=True, nogil=True, parallel=True)
def _walk_units(solid, geometry, first, last, points, lengths, kinds, vertex_slots, strip_slots, write):
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


# ----------------------------------------------------------------------------------------------------------------
# VTK filters
# ----------------------------------------------------------------------------------------------------------------
class TowerFilter(VoxelSurfaceFilter):
    """VTK filter around :func:`tower_strips`: an image's visible voxel faces as triangle strips (``GetStrips``).

    Threshold and geometry as in :class:`algorithms.voxel_faces.VoxelSurfaceFilter`.

    Examples
    --------
    >>> from algorithms._vtk import image_from_array, run_algorithm
    >>> f = TowerFilter()
    >>> f.SetInputDataObject(0, image_from_array(volume, spacing, origin))
    >>> f.SetThreshold(300.0)
    >>> polydata = run_algorithm(f)    # polydata.GetStrips() holds one cell per strip
    """

    @staticmethod
    def _extract(array, **options) -> TriangleStrips:
        return tower_strips(array, **options)


class HybridFilter(VoxelSurfaceFilter):
    """VTK filter around :func:`hybrid`: short strips as triangles (``GetPolys``), long ones as strips.

    ``SetMaxStripVertices(L)`` (default 10, as in the source) sets the longest strip that is converted.
    Threshold and geometry as in :class:`algorithms.voxel_faces.VoxelSurfaceFilter`.
    """

    def __init__(self) -> None:
        super().__init__()
        self._max_strip_vertices = 10

    def SetMaxStripVertices(self, value: int) -> None:  # noqa: N802 - VTK naming
        value = int(value)
        if value < 0:
            raise ValueError(f"max_strip_vertices must be >= 0, got {value}")
        if value != self._max_strip_vertices:
            self._max_strip_vertices = value
            self.Modified()

    def GetMaxStripVertices(self) -> int:  # noqa: N802
        return self._max_strip_vertices

    def _extract(self, array, *, progress, **options) -> HybridSurface:
        strips = tower_strips(array, progress=scaled(progress, 0.0, 0.9), **options)
        surface = hybrid(strips, max_strip_vertices=self._max_strip_vertices)
        report(progress, 1.0)
        return surface


__all__ = [
    "STRIP_BOTTOM",
    "STRIP_CIRCUMFERENCE",
    "STRIP_TOP",
    "HybridFilter",
    "HybridSurface",
    "TowerFilter",
    "TriangleStrips",
    "hybrid",
    "tower_strips",
]
