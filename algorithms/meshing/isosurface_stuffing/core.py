"""Isosurface stuffing: a tetrahedral mesh of guaranteed quality filling an isosurface of a volume.

Method (source 002, chapter 4; Labelle & Shewchuk 2007):

1. **Lattice** (:mod:`.lattice`): the body-centred cubic lattice of spacing ``h`` (outer grid plus the cell
   centres) over the box of the shape, one layer of points beyond it on every side.
2. **Field**: ``f = value - iso`` (inside ``value >= iso``; ``inside="below"`` negates it, for signed distance
   fields that are negative inside) by trilinear interpolation of the volume at every lattice point, in mm; samples
   outside the volume read as its minimum, so a shape cut by the volume's border is closed there. Each point is
   classified +, - or 0.
3. **Cut points**: on every edge whose ends have opposite signs, the zero of the interpolated field by bisection
   (``cut="bisection"``: 10 halvings, then the zero of the line through the last bracket's ends) or by linear interpolation of the end values (``cut="linear"``, exact for a
   distance field of a plane).
4. **Warp**: a point with a cut point on one of its 14 edges closer than ``alpha`` times the edge's length
   (``alpha_long`` for black edges of length h, ``alpha_short`` for red ones of length h sqrt(3)/2) moves to the
   closest such cut point and becomes 0; cut points on its other edges disappear. Positive points warp first, then
   negative ones (to cut points whose other end is still positive): a sequential order the paper allows, done in
   parallel because points of one sign share no cut edge.
5. **Stencils** (:mod:`.stencils`, :mod:`.fill`): every BCC tetrahedron with a positive vertex is filled from the
   table of 81 sign patterns, quadrilaterals split by the parity rule. Lattice and cut points are numbered once
   each: an indexed mesh.

Guarantee (the paper's computer-assisted proof): with ``alpha = (0.24999, 0.41189)`` ("10.7") every dihedral
angle lies in [10.7, 164.8] degrees; with ``(0.21509, 0.35900)`` ("8.9") in [8.9, 158.8] degrees. The boundary
faces (faces used once, all on ``f = 0``) form a closed, outward surface mesh of the same quality.

Kernels run in parallel over lattice layers (numba); memory per lattice point is reported against source 002's
44 bytes (:mod:`.lattice`).

References
----------
F. Labelle and J. R. Shewchuk, "Isosurface stuffing: fast tetrahedral meshes with good dihedral angles", ACM
Transactions on Graphics 26(3), SIGGRAPH 2007. doi:10.1145/1276377.1276448.
Source 002 (K. Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009; see
docs/references.md), chapter 4 "Tetraedisierung".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...common.mesh import TetMesh, TriangleMesh
from ...common.progress import ProgressCallback, report
from ...common.validation import validated_numeric_volume, validated_origin, validated_spacing
from . import fill, kernels, stencils
from .lattice import Lattice, estimated_bytes, format_gib, lattice_around, physical_memory

__all__ = ["ALPHAS", "ANGLE_BOUNDS", "StuffingResult", "isosurface_stuffing", "resolve_alphas", "stuffing_table"]

#: ``(alpha_long, alpha_short)`` by the name of their lower angle bound (Labelle & Shewchuk 2007).
ALPHAS = {"10.7": (0.24999, 0.41189), "8.9": (0.21509, 0.35900)}
#: Guaranteed dihedral-angle bounds (degrees) of each alpha pair.
ANGLE_BOUNDS = {"10.7": (10.7, 164.8), "8.9": (8.9, 158.8)}
BISECTION_STEPS = 10
#: Share of the machine's memory one run may plan to use.
MEMORY_SHARE = 0.6


def resolve_alphas(alpha) -> tuple[str, tuple[float, float]]:
    """``("10.7" | "8.9", (alpha_long, alpha_short))`` from a name (``"10.7"``, ``10.7``, ``"8.9"``...)."""
    key = f"{float(alpha):g}" if isinstance(alpha, (int, float)) else str(alpha).strip()
    if key not in ALPHAS:
        raise ValueError(f"alpha must name a bound of the paper: {' or '.join(ALPHAS)} (degrees), got {alpha!r}")
    return key, ALPHAS[key]


def stuffing_table():
    """The stencil table the kernels take: ``(counts, faces, n_faces, tets)`` (see :func:`.stencils.build_table`)."""
    return stencils.COUNTS, stencils.FACES, stencils.N_FACES, stencils.TETS


@dataclass
class StuffingResult:
    """The tetrahedral mesh, its boundary triangles and the numbers of the run.

    Attributes
    ----------
    mesh : TetMesh
        Points ``(n, 3)`` float64 (mm, volume frame) and tetrahedra ``(m, 4)`` int64 of positive volume.
    boundary : ndarray, shape (b, 3), int64
        The boundary triangles (indices into ``mesh.points``), counter-clockwise seen from outside.
    on_surface : ndarray, shape (n,), bool
        Which points lie on the isosurface (cut points and zero lattice points, warped or not).
    seconds : dict
        ``field``, ``cut``, ``warp``, ``stencil``, ``output`` and ``total`` (s).
    stats : dict
        Lattice size, points near the surface, warped points, cut points, bytes per lattice point (and source
        002's 44), ``h``, ``alpha``...
    """

    mesh: TetMesh
    boundary: np.ndarray
    on_surface: np.ndarray
    seconds: dict[str, float] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)

    def boundary_mesh(self) -> TriangleMesh:
        """The boundary as a compact :class:`TriangleMesh` (only the points it uses)."""
        used, triangles = np.unique(self.boundary, return_inverse=True)
        return TriangleMesh(self.mesh.points[used].astype(np.float64), triangles.reshape(-1, 3).astype(np.int64))


def _inside_box(array: np.ndarray, iso: float, above: bool):
    """Index bounds ``(lower, upper)`` (``(i, j, k)``) of the voxels inside, or None when there are none."""
    mask = array >= iso if above else array <= iso
    bounds = []
    for axis in (2, 1, 0):  # i, j, k
        other = tuple(a for a in range(3) if a != axis)
        hit = np.flatnonzero(mask.any(axis=other))
        if hit.size == 0:
            return None, 0
        bounds.append((hit[0], hit[-1]))
    return np.array(bounds, dtype=np.float64), int(np.count_nonzero(mask))


def isosurface_stuffing(
    volume,
    iso: float,
    *,
    h: float,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
    alpha="10.7",
    inside: str = "above",
    cut: str = "bisection",
    memory_limit: int | None = None,
    table=None,
    progress: ProgressCallback = None,
) -> StuffingResult:
    """Fill the isosurface ``value = iso`` of a volume with tetrahedra by isosurface stuffing.

    Parameters
    ----------
    volume : ndarray, shape (nz, ny, nx)
        Scalar samples indexed ``[k, j, i]`` (any real dtype).
    iso : float
        The isovalue, inside the volume's value range.
    h : float
        Lattice spacing in mm (black edges have length h).
    spacing, origin : (x, y, z)
        Voxel size and position of sample (0, 0, 0), mm.
    alpha : "10.7" or "8.9"
        The paper's parameter pair, named by its lower angle bound (:data:`ALPHAS`).
    inside : {"above", "below"}
        Inside is ``value >= iso`` ("above", CT bone) or ``value <= iso`` ("below", distance fields negative
        inside).
    cut : {"bisection", "linear"}
        How cut points are found on the interpolated field.
    memory_limit : int, optional
        Bytes a run may plan to use (default 60 % of the machine's memory).
    table : tuple, optional
        A stencil table ``(counts, faces, n_faces, tets)`` in place of :func:`stuffing_table` (tests).
    progress : callable, optional
        Called with the fraction done between passes; may raise ``OperationCancelled``.

    Returns
    -------
    StuffingResult

    Raises
    ------
    ValueError
        For a volume that is not 3D or holds NaN, an isovalue outside the values (or a constant volume), no voxel
        inside, ``h`` not positive or larger than the volume, a lattice that would not fit in memory (the size in
        GiB is given), an unknown ``alpha``, ``inside`` or ``cut``; all before any large allocation.
    """
    start = time.perf_counter()
    array = validated_numeric_volume(volume, min_size=2, finite=True)
    spacing = validated_spacing(spacing)
    origin = validated_origin(origin)
    name, (alpha_long, alpha_short) = resolve_alphas(alpha)
    if inside not in ("above", "below"):
        raise ValueError(f"inside must be 'above' or 'below', got {inside!r}")
    if cut not in ("bisection", "linear"):
        raise ValueError(f"cut must be 'bisection' or 'linear', got {cut!r}")
    h = float(h)
    if not np.isfinite(h) or h <= 0:
        raise ValueError(f"the lattice spacing h must be a positive number of mm, got {h}")
    iso = float(iso)
    low, high = float(array.min()), float(array.max())
    if low == high:
        raise ValueError(f"the field is empty: {low:g} everywhere, so there is no surface to fill")
    if not np.isfinite(iso) or not low <= iso <= high:
        raise ValueError(f"the isovalue {iso:g} lies outside the values of the volume ({low:g} to {high:g}); "
                         "choose one inside that range")
    extent = spacing * (np.array(array.shape[::-1]) - 1)
    if h > extent.min():
        raise ValueError(f"h = {h:g} mm is larger than the volume ({' x '.join(f'{e:g}' for e in extent)} mm); "
                         "choose a smaller lattice spacing")
    above = inside == "above"
    box, inside_voxels = _inside_box(array, iso, above)
    if box is None:
        raise ValueError(f"no voxel is {'at or above' if above else 'at or below'} {iso:g}: the field is empty")
    lower = origin + spacing * (box[:, 0] - 1)
    upper = origin + spacing * (box[:, 1] + 1)
    lattice = lattice_around(lower, upper, h)
    needed = estimated_bytes(lattice, inside_voxels * float(np.prod(spacing)))
    limit = memory_limit if memory_limit is not None else int(MEMORY_SHARE * (physical_memory() or 8 * 2**30))
    if needed > limit:
        raise ValueError(f"h = {h:g} mm needs a lattice of {lattice.n_points:,} points and about "
                         f"{format_gib(needed)}, more than the {format_gib(limit)} allowed; choose a larger h")
    counts, faces, n_faces, tets_table = table if table is not None else stuffing_table()

    seconds: dict[str, float] = {}
    tick = time.perf_counter()
    values = np.ascontiguousarray(array, dtype=np.float32)
    pad = low if low < iso else iso - max(1.0, high - low)
    if not above:
        pad = high if high > iso else iso + max(1.0, high - low)
    geometry = np.array([*origin, *spacing, iso, pad, 1.0 if above else -1.0], dtype=np.float64)
    lat = lattice.vector
    blocks = tuple(-(-n // kernels.BLOCK) for n in values.shape)
    lows = np.empty(blocks, dtype=np.float64)
    highs = np.empty(blocks, dtype=np.float64)
    kernels.block_ranges(values, lows, highs)
    sign_o = np.empty(lattice.outer_shape, dtype=np.int8)
    sign_i = np.empty(lattice.inner_shape, dtype=np.int8)
    row_o = np.zeros(lattice.outer_shape[:2], dtype=np.uint8)
    row_i = np.zeros(lattice.inner_shape[:2], dtype=np.uint8)
    kernels.classify(values, geometry, lat, lows, highs, sign_o, sign_i, row_o, row_i)
    seconds["field"] = time.perf_counter() - tick
    report(progress, 0.2)

    tick = time.perf_counter()
    near_o = np.zeros(lattice.outer_shape, dtype=np.uint8)
    near_i = np.zeros(lattice.inner_shape, dtype=np.uint8)
    kernels.mark_near(sign_o, sign_i, row_o, row_i, near_o, near_i)
    ref_o, ref_i, rec_point = _records(near_o, near_i)
    del near_o, near_i
    n_records = len(rec_point)
    rec_pos = _positions(rec_point, lattice)
    rec_t = np.full((n_records, 7), -1.0, dtype=np.float32)
    kernels.compute_cuts(values, geometry, lat, sign_o, sign_i, rec_point, rec_t, BISECTION_STEPS, cut == "linear")
    seconds["cut"] = time.perf_counter() - tick
    report(progress, 0.4)

    tick = time.perf_counter()
    warped = np.zeros(n_records, dtype=np.uint8)
    for phase in (1, -1):
        kernels.warp(sign_o, sign_i, ref_o, ref_i, rec_point, rec_t, rec_pos, lat, alpha_long, alpha_short, phase,
                     warped)
    seconds["warp"] = time.perf_counter() - tick
    report(progress, 0.5)

    tick = time.perf_counter()
    vid_o, vid_i, n_lattice = _vertex_ids(sign_o, sign_i)
    cut_counts = np.zeros(n_records, dtype=np.int64)
    rec_cut = np.full((n_records, 7), -1, dtype=np.int32)
    kernels.number_cuts(sign_o, sign_i, rec_point, rec_t, cut_counts, rec_cut, lat, np.empty((0, 3)), True,
                        cut_counts)
    cut_first = np.cumsum(cut_counts) - cut_counts
    n_cuts = int(cut_counts.sum())
    points = np.empty((n_lattice + n_cuts, 3), dtype=np.float64)
    _vertex_positions(points, vid_o, vid_i, ref_o, ref_i, rec_pos, lattice)
    kernels.number_cuts(sign_o, sign_i, rec_point, rec_t, cut_first, rec_cut, lat, points[n_lattice:], False,
                        cut_counts)
    report(progress, 0.6)
    surface_faces = _SURFACE_FACES if table is None else surface_face_counts(counts, tets_table, n_faces)
    row_counts = np.zeros(lattice.outer_shape[:2] + (2,), dtype=np.int64)
    fill.count(sign_o, sign_i, row_o, row_i, counts, faces, n_faces, surface_faces, fill.RING, row_counts)
    report(progress, 0.75)
    flat = row_counts.reshape(-1, 2)
    first = (np.cumsum(flat, axis=0) - flat).reshape(row_counts.shape)
    tets = np.empty((int(flat[:, 0].sum()), 4), dtype=np.int32)
    candidates = np.empty((int(flat[:, 1].sum()), 3), dtype=np.int32)
    fill.stuff(sign_o, sign_i, vid_o, vid_i, ref_o, ref_i, rec_cut, n_lattice, counts, faces, n_faces, tets_table,
               stencils.EDGE_ENDS, fill.RING, fill.OUTWARD_FACES, first, row_counts, tets, candidates)
    seconds["stencil"] = time.perf_counter() - tick
    report(progress, 0.9)

    tick = time.perf_counter()
    boundary = _faces_used_once(candidates)
    mesh = TetMesh(points, tets)
    seconds["output"] = time.perf_counter() - tick
    seconds["total"] = time.perf_counter() - start
    report(progress, 1.0)
    stats = {
        "h": h, "iso": iso, "inside": inside, "alpha": name, "alpha_long": alpha_long, "alpha_short": alpha_short,
        "cut": cut, "lattice_cells": list(lattice.cells), "lattice_points": lattice.n_points,
        "near_surface_points": n_records, "warped_points": int(warped.sum()), "cut_points": n_cuts,
        "lattice_vertices": n_lattice, "tetrahedra": mesh.n_tetrahedra, "points": mesh.n_points,
        "boundary_triangles": int(len(boundary)),
        "bytes_per_lattice_point": lattice.bytes_per_point(n_records), "source_bytes_per_lattice_point": 44,
    }
    on_surface = np.ones(mesh.n_points, dtype=bool)
    on_surface[:n_lattice] = False
    for vid, sign in ((vid_o, sign_o), (vid_i, sign_i)):
        on_surface[vid[(vid >= 0) & (sign == 0)]] = True
    return StuffingResult(mesh, boundary, on_surface, seconds, stats)


def surface_face_counts(counts, tets_table, n_faces) -> np.ndarray:
    """Faces with three vertices on the surface per pattern and parity variant (256, 4): the candidate boundary
    faces each stencil writes. A vertex is on the surface when it is a cut point or a zero lattice vertex."""
    out = np.zeros((256, tets_table.shape[1]), dtype=np.int64)
    for pattern in range(256):
        if counts[pattern] <= 0:
            continue
        zero = [((pattern >> (2 * (3 - s))) & 3) == stencils.ZERO for s in range(4)]
        for variant in range(tets_table.shape[1]):
            for tet in tets_table[pattern, variant, :counts[pattern]]:
                for face in fill.OUTWARD_FACES:
                    out[pattern, variant] += all(tet[c] >= 4 or zero[tet[c]] for c in face)
    return out


_SURFACE_FACES = surface_face_counts(stencils.COUNTS, stencils.TETS, stencils.N_FACES)


def _records(near_o: np.ndarray, near_i: np.ndarray):
    """Record references (dense int32, -1 for none) and ``(grid, i, j, k)`` of the flagged points, outer first."""
    records = []
    refs = []
    start = 0
    for grid, near in enumerate((near_o, near_i)):
        flat = np.flatnonzero(near.ravel())
        ref = np.full(near.shape, -1, dtype=np.int32)
        ref.ravel()[flat] = np.arange(start, start + flat.size, dtype=np.int32)
        k, j, i = np.unravel_index(flat, near.shape)
        records.append(np.stack([np.full(flat.size, grid), i, j, k], axis=1).astype(np.int32))
        refs.append(ref)
        start += flat.size
    return refs[0], refs[1], np.concatenate(records)


def _positions(rec_point: np.ndarray, lattice: Lattice) -> np.ndarray:
    """Lattice positions (mm) of ``(grid, i, j, k)`` rows."""
    offset = 0.5 * rec_point[:, :1].astype(np.float64)
    return np.asarray(lattice.origin) + lattice.h * (rec_point[:, 1:].astype(np.float64) + offset)


def _vertex_ids(sign_o: np.ndarray, sign_i: np.ndarray):
    """Vertex ids of the lattice points of the output: positive points, and zero points with a positive
    neighbour; outer points first. Dense int32 arrays (-1 for none) and the count."""
    keep = [sign_o > 0, sign_i > 0]
    zeros_o = np.argwhere(sign_o == 0)
    zeros_i = np.argwhere(sign_i == 0)
    if len(zeros_o) or len(zeros_i):
        zeros = np.concatenate([zeros_o, zeros_i]).astype(np.int64)
        grids = np.concatenate([np.zeros(len(zeros_o), np.int64), np.ones(len(zeros_i), np.int64)])
        used = np.zeros(len(zeros), dtype=np.uint8)
        kernels.zero_vertices(sign_o, sign_i, zeros, grids, used)
        for grid, rows in ((0, zeros_o), (1, zeros_i)):
            chosen = rows[used[grids == grid].astype(bool)]
            keep[grid][tuple(chosen.T)] = True
    ids = []
    start = 0
    for mask in keep:
        vid = np.full(mask.shape, -1, dtype=np.int32)
        flat = np.flatnonzero(mask.ravel())
        vid.ravel()[flat] = np.arange(start, start + flat.size, dtype=np.int32)
        ids.append(vid)
        start += flat.size
    return ids[0], ids[1], start


def _vertex_positions(points, vid_o, vid_i, ref_o, ref_i, rec_pos, lattice: Lattice) -> None:
    """Positions of the lattice vertices: the lattice position, or the warped one of its record."""
    for grid, (vid, ref) in enumerate(((vid_o, ref_o), (vid_i, ref_i))):
        flat = np.flatnonzero(vid.ravel() >= 0)
        k, j, i = np.unravel_index(flat, vid.shape)
        ids = vid.ravel()[flat]
        points[ids] = np.asarray(lattice.origin) + lattice.h * (np.stack([i, j, k], axis=1) + 0.5 * grid)
        records = ref.ravel()[flat]
        has = records >= 0
        points[ids[has]] = rec_pos[records[has]]


def _faces_used_once(candidates: np.ndarray) -> np.ndarray:
    """The candidate faces whose vertex set occurs once (the others are shared by two tetrahedra)."""
    if len(candidates) == 0:
        return np.empty((0, 3), dtype=np.int64)
    key = np.sort(candidates, axis=1)
    order = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))
    ordered = key[order]
    same_next = np.all(ordered[1:] == ordered[:-1], axis=1)
    single = np.ones(len(ordered), dtype=bool)
    single[1:] &= ~same_next
    single[:-1] &= ~same_next
    return candidates[np.sort(order[single])].astype(np.int64)
