"""Voxel surfaces as triangle strips: the tower algorithm of source 000 and its hybrid variant.

Method
------
The tower algorithm draws exactly the faces of :func:`algorithms.surfaces.voxel_faces.voxel_faces` (every face of a
solid voxel whose neighbour is empty or outside the volume), but as triangle strips: no indices, fewer vertices. It
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

Each quad is split along the same diagonal as in :func:`algorithms.surfaces.voxel_faces.voxel_faces`, so both
representations rasterise every face as the same two triangles.

Hybrid (source 000, section 6.3): after the tower pass, strips of at most ``L`` vertices (the source used 10) are
turned back into indexed triangles exactly as the baseline stores faces (4 vertices and 6 indices per face, the
same diagonal), to save the cost of many tiny draw calls; longer strips stay strips.

Axis order: the volume array is ``(nz, ny, nx)``, indexed ``[k, j, i]``; spacing and origin are ``(x, y, z)`` =
``(i, j, k)``. A face corner is at ``origin + spacing * ((i, j, k) +- 0.5)`` in the volume frame (mm).

References
----------
Source 000 (Dutch BSc thesis on voxel models as triangle strips, see docs/references.md): section 3 (triangle
strips and culling), section 6 (the tower algorithm, algorithms 2 and 3; linear, about 5N steps, section 6.2),
section 6.3 (hybrid) and section 7 (equivalence with the baseline).
F. Evans, S. Skiena, A. Varshney, "Optimizing triangle strips for fast rendering", Proc. IEEE Visualization '96,
doi:10.1109/VISUAL.1996.568125 (stripping general meshes, the problem VTK's vtkStripper solves greedily).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ...common.mesh import TriangleMesh, TriangleStrips, csr_ranks, joined_polydata
from ...common.progress import ProgressCallback, report, scaled
from ...common.validation import validated_geometry, validated_solid
from ..voxel_faces import face_triangles
from .kernels import STRIP_BOTTOM, STRIP_CIRCUMFERENCE, STRIP_TOP, walk_units

#: Voxels per parallel launch of the walk (progress is reported between launches).
_CHUNK_VOXELS = 8_000_000


@dataclass(frozen=True)
class TowerStrips(TriangleStrips):
    """A voxel surface as triangle strips whose vertices are stored in strip order (no indices): the tower
    algorithm's result, a :class:`~algorithms.common.mesh.TriangleStrips` that also knows its strips' kinds and the
    voxel grid.

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

    kinds: np.ndarray
    spacing: tuple[float, float, float]
    origin: tuple[float, float, float]


@dataclass(frozen=True)
class HybridSurface:
    """A voxel surface as indexed triangles (the short strips, stored like the baseline) plus the long strips, over
    one point list (triangle points first).

    Attributes
    ----------
    faces : TriangleMesh
        The ``F`` faces converted from short strips: points ``(4F, 3)`` float32, four per face, counter-clockwise
        from outside, and triangles ``(2F, 3)`` ``(4f, 4f+1, 4f+2)`` and ``(4f, 4f+2, 4f+3)`` as in the baseline
        (int32, int64 beyond 2**31 points).
    strips : TowerStrips
        The strips longer than ``max_strip_vertices``, unchanged.
    max_strip_vertices : int
        ``L``: strips with at most this many vertices were converted.
    """

    faces: TriangleMesh
    strips: TowerStrips
    max_strip_vertices: int

    @property
    def points(self) -> np.ndarray:
        """The converted faces' corners, ``(4F, 3)``."""
        return self.faces.points

    @property
    def triangles(self) -> np.ndarray:
        """The converted faces' triangles, ``(2F, 3)``, indices into :attr:`points`."""
        return self.faces.triangles

    @property
    def spacing(self) -> tuple[float, float, float]:
        return self.strips.spacing

    @property
    def origin(self) -> tuple[float, float, float]:
        return self.strips.origin

    @property
    def n_triangles(self) -> int:
        return self.faces.n_triangles + self.strips.n_triangles

    def to_polydata(self) -> vtkPolyData:
        """Triangles (``SetPolys``) and strips (``SetStrips``) over one point list: triangle points first."""
        return joined_polydata(self.faces, self.strips)


def tower_strips(
    volume,
    *,
    threshold=None,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
    progress: ProgressCallback = None,
) -> TowerStrips:
    """The visible voxel faces as triangle strips by the tower algorithm (source 000, section 6).

    Parameters
    ----------
    volume : ndarray, shape (nz, ny, nx)
        A boolean mask (True = solid) or a scalar volume, indexed ``[k, j, i]``; ``k`` is the height axis along
        which the slices are walked.
    threshold, spacing, origin :
        As for :func:`algorithms.surfaces.voxel_faces.voxel_faces`: the solid threshold of a scalar volume (omitted
        for a boolean mask), the voxel size ``(sx, sy, sz)`` and the centre of voxel ``(0, 0, 0)``, in mm.
    progress : callable, optional
        Called with the fraction done between chunks of slices; may raise ``OperationCancelled``.

    Returns
    -------
    TowerStrips
        For each slice ``k`` in turn: its circumference strips (one per boundary loop), then the top strips of
        slice ``k - 1`` and bottom strips of slice ``k`` on the rows where the two differ; the top strips of the
        last slice come last. Every strip has an even number of vertices; together they draw each visible face
        exactly once, as two outward-facing triangles.

    Raises
    ------
    ValueError
        See :func:`algorithms.common.validation.validated_solid` and
        :func:`~algorithms.common.validation.validated_geometry`.

    Notes
    -----
    Time and memory are linear in the number of voxels. Slices are independent and run in parallel (numba): a
    counting pass gives each slice's exact output size, and a second pass writes every slice into its own range
    of the output. Vertex positions are computed exactly as the baseline computes them (float64, stored as
    float32), so both representations hold bit-identical corners.

    References
    ----------
    Source 000 (Dutch BSc thesis on voxel models as triangle strips, see docs/references.md), sections 6
    (algorithms 2 and 3) and 7.

    Examples
    --------
    >>> import numpy as np
    >>> strips = tower_strips(np.ones((1, 1, 1), dtype=bool))
    >>> strips.n_strips, strips.n_vertices, strips.n_triangles   # one loop of 4 walls, one top, one bottom
    (3, 18, 12)
    """
    array, threshold = validated_solid(volume, threshold)
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
    return TowerStrips(points=points, offsets=offsets, kinds=kinds, spacing=spacing_t, origin=origin_t)


def _walk(solid, geometry, points, lengths, kinds, vertex_slots, strip_slots, write, progress) -> None:
    """Run every unit, in chunks with progress between them (see :func:`.kernels.walk_units`)."""
    n_units = solid.shape[0] - 1
    # Chunks of about _CHUNK_VOXELS voxels: few parallel launches (each ends at a barrier of all threads), yet
    # progress several times a second on large volumes.
    chunk = max(1, -(-_CHUNK_VOXELS // (solid.shape[1] * solid.shape[2])))
    for first in range(0, n_units, chunk):
        last = min(n_units, first + chunk)
        walk_units(solid, geometry, first, last, points, lengths, kinds, vertex_slots, strip_slots, write)
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
    strips_or_volume : TowerStrips or ndarray, shape (nz, ny, nx)
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
    Source 000 (Dutch BSc thesis on voxel models as triangle strips, see docs/references.md), sections 6.3 and 9.3.
    """
    if isinstance(max_strip_vertices, (bool, np.bool_)) or not isinstance(max_strip_vertices, (int, np.integer)):
        raise ValueError(f"max_strip_vertices must be an integer, got {max_strip_vertices!r}")
    if max_strip_vertices < 0:
        raise ValueError(f"max_strip_vertices must be >= 0, got {max_strip_vertices}")
    if isinstance(strips_or_volume, TowerStrips):
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
    quad_start = np.repeat(strip_first, quads_per_strip) + 2 * csr_ranks(quads_per_strip)
    corners = np.take(strips.points, quad_start[:, None] + np.array([1, 3, 2, 0]), axis=0)  # (F, 4, 3)
    triangles = face_triangles(len(quad_start))

    kept_vertices = np.repeat(~short, lengths)
    kept_lengths = lengths[~short]
    kept_offsets = np.zeros(len(kept_lengths) + 1, dtype=np.int64)
    np.cumsum(kept_lengths, out=kept_offsets[1:])
    long_strips = TowerStrips(
        points=np.compress(kept_vertices, strips.points, axis=0),
        offsets=kept_offsets,
        kinds=strips.kinds[~short],
        spacing=strips.spacing,
        origin=strips.origin,
    )
    return HybridSurface(
        faces=TriangleMesh(corners.reshape(-1, 3), triangles),
        strips=long_strips,
        max_strip_vertices=int(max_strip_vertices),
    )


__all__ = [
    "STRIP_BOTTOM",
    "STRIP_CIRCUMFERENCE",
    "STRIP_TOP",
    "HybridSurface",
    "TowerStrips",
    "hybrid",
    "tower_strips",
]
