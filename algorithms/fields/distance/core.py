"""Signed distance fields of triangle meshes: exact distances in a band around the mesh, the sign from voxelisation,
and outside the band either a clamp or a propagation that still measures every far voxel against a real triangle.

Method (source 002, chapter 3, sections 3.1.3 and 3.2)
-----------------------------------------------------
Source 002 computes the distances slice by slice. Every triangle gets a bounding region grown by the band width
``d``; the triangles are sorted by height so that a slice visits only the active ones; every voxel of the slice
inside a triangle's region gets the distance to that triangle, computed in the triangle's own frame (``t`` along
the normal, ``r`` along the longest edge, ``s`` towards the third vertex; the triangle described by ``a, b, h``;
the projected point classified into the regions I-VI of the source's figure 3.3), and keeps the smallest. Here:

- the regions are scanned row by row: for every slice and every active region, the rows the region meets and, per
  row, the run of voxels inside it (from the region's half-spaces); along a run the frame coordinates change
  linearly (the source's interpolated texture coordinates), :mod:`.kernels`; slices run in parallel;
- ``regions="box"`` uses the source's own region, the triangle's box grown by ``d`` along ``r``, ``s`` and ``t``
  (Erleben and Dohlmann, as in source 002's section 3.2); ``regions="characteristic"`` (default) the tighter
  regions source 002 names as the way to speed it up ("besser zugeschnittene Polyeder"): the triangle's prism, its
  edges' wedges and its vertices' cones, which hold every point whose nearest mesh point lies on them
  (:mod:`.characteristics`, after Mauch's characteristics/scan-conversion method of section 3.1.3). Both give the
  same, exact, distances in the band; the characteristic regions overlap far less;
- the sign comes from :func:`algorithms.fields.voxelise.voxelise` (parity, or the winding number for meshes with holes), correct
  everywhere, never from a plane test at the nearest triangle (source 002, figure 3.4: such tests fail at sharp
  angles);
- outside the band the field is clamped to ``+-d`` or propagated (:mod:`.propagate`).

Every voxel whose distance to the mesh is at most ``d`` gets that distance exactly (float64 arithmetic, stored as
float32 mm) and the index of a nearest triangle.

Frames and array order
----------------------
Points are ``(x, y, z)`` LPS mm; the grid (:class:`algorithms.common.grid.Grid`, any spacing, origin and rotation)
maps them once to its own frame in mm, ``(p - origin) @ direction``, where voxel ``(i, j, k)`` is at ``(i sx, j sy,
k sz)``. Fields have the grid's NumPy shape ``(nz, ny, nx)``, indexed ``[k, j, i]``; negative inside.

References
----------
Source 002 (German MSc thesis "Vergleich von Volumenmodellen", see docs/references.md), chapter 3
"Distanztransformation", sections 3.1.3, 3.2 and table 3.1.
C. Sigg, R. Peikert, M. Gross, "Signed distance transform using graphics hardware", IEEE Visualization 2003.
K. Erleben, H. Dohlmann, "Signed distance fields using single-pass GPU scan conversion of tetrahedra", GPU Gems 3,
2008. S. Mauch, "Efficient algorithms for solving static Hamilton-Jacobi equations", PhD thesis, Caltech, 2003.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numba
import numpy as np

from ...common.grid import Grid
from ...common.progress import ProgressCallback, report, scaled
from ..voxelise import voxelise
from ..voxelise.core import _validated as validated_mesh
from . import characteristics
from . import kernels
from . import scan
from .propagate import propagate

__all__ = ["OUTSIDE_RULES", "REGIONS", "BandDistances", "DistanceField", "MeshFrames", "band_distances",
           "band_from_percent", "exact_distances", "signed_distance"]

OUTSIDE_RULES = ("clamp", "propagate")
REGIONS = ("characteristic", "box")
#: Refuse work lists larger than this (slice-region pairs, 4 bytes each): about 4 GiB.
MAX_SLICE_ENTRIES = 1 << 30


@dataclass
class MeshFrames:
    """A mesh in a grid's frame (mm) with each triangle's frame and the mesh's edges and vertex neighbourhoods."""

    points: np.ndarray  # (n, 3) float64, grid frame mm
    triangles: np.ndarray  # (m, 3) int64
    frames: np.ndarray  # (m, 15)
    frame_vertices: np.ndarray  # (m, 3): v0, v1, v2 of each frame
    rotation: np.ndarray  # (m,)
    degenerate: np.ndarray  # (m,) bool
    topology: tuple = ()

    @classmethod
    def build(cls, points, triangles, grid: Grid) -> "MeshFrames":
        local = np.ascontiguousarray((np.asarray(points, np.float64) - np.asarray(grid.origin)) @ grid.direction_matrix)
        m = len(triangles)
        frames = np.empty((m, kernels.FRAME_SIZE))
        frame_vertices = np.empty((m, 3), dtype=np.int64)
        rotation = np.empty(m, dtype=np.int64)
        degenerate = np.empty(m, dtype=np.bool_)
        kernels.triangle_frames(local, triangles, frames, frame_vertices, rotation, degenerate)
        return cls(local, triangles, frames, frame_vertices, rotation, degenerate)

    def with_topology(self) -> "MeshFrames":
        if not self.topology:
            self.topology = characteristics.mesh_topology(self.triangles, len(self.points))
        return self


@dataclass(frozen=True)
class BandDistances:
    """Exact distances within ``band_mm`` of a mesh: ``distance2`` (squared mm, float32, ``inf`` where no region
    reached) and ``nearest`` (triangle index, -1 where none); voxels with ``distance2 <= band_mm**2`` are exact."""

    distance2: np.ndarray
    nearest: np.ndarray
    band_mm: float
    stats: dict = field(default_factory=dict)

    @property
    def in_band(self) -> np.ndarray:
        return self.distance2 <= np.float32(self.band_mm) ** 2


def _validated(points, triangles, grid) -> tuple[np.ndarray, np.ndarray]:
    return validated_mesh(points, triangles, grid, "parity")


def _slack(grid: Grid) -> float:
    """Margin (mm) added to every region so that rounding never drops a voxel on a region's boundary."""
    return 1e-6 * min(grid.spacing) + 1e-12 * max(1.0, float(np.max(np.abs(grid.world_bounds))))


def band_distances(points, triangles, grid: Grid, band_mm: float, *, regions: str = "characteristic",
                   mesh: MeshFrames | None = None, progress: ProgressCallback = None) -> BandDistances:
    """Exact unsigned distances (mm) from the voxel centres of ``grid`` to a triangle mesh, within ``band_mm``.

    Parameters
    ----------
    points : ndarray (n, 3)
        Vertex positions ``(x, y, z)``, LPS mm.
    triangles : ndarray (m, 3) of int
        Vertex indices (any mesh: open, non-manifold or inconsistently oriented meshes are fine).
    grid : Grid
        Target grid (any spacing, origin and rotation).
    band_mm : float
        Band width d in mm (positive; ``inf`` for the whole grid).
    regions : {"characteristic", "box"}
        The region scanned per triangle (see the module notes); both give the same distances.
    mesh : MeshFrames, optional
        The mesh already in the grid's frame (reused by :func:`signed_distance`).
    progress : callable, optional
        Called with the fraction done; may raise :class:`~algorithms.common.progress.OperationCancelled`.

    Returns
    -------
    BandDistances
        ``distance2`` and ``nearest`` of shape ``grid.shape`` ``(nz, ny, nx)``; ``stats`` holds the number of
        regions, slice-region pairs and distance evaluations.

    Raises
    ------
    ValueError
        Bad points, triangles, grid, band or region kind; a band so wide that the work lists would not fit.
    """
    start_time = time.perf_counter()
    if mesh is None:
        points, triangles = _validated(points, triangles, grid)
    if regions not in REGIONS:
        raise ValueError(f"regions must be one of {', '.join(REGIONS)}, got {regions!r}")
    band_mm = float(band_mm)
    if not band_mm > 0:
        raise ValueError(f"the band width must be a positive number of mm, got {band_mm}")
    nx, ny, nz = grid.dimensions
    spacing = np.asarray(grid.spacing, dtype=np.float64)
    diagonal = float(np.linalg.norm((np.asarray(grid.dimensions) - 1) * spacing))
    distance2 = np.full(grid.shape, np.inf, dtype=np.float32)
    nearest = np.full(grid.shape, -1, dtype=np.int32)
    if mesh is None:
        if len(triangles) == 0:
            report(progress, 1.0)
            return BandDistances(distance2, nearest, band_mm, {"regions": 0})
        mesh = MeshFrames.build(points, triangles, grid)
    # no voxel is farther from the mesh than the grid's diagonal plus the mesh's distance to the grid
    low = mesh.points.min(axis=0)
    high = mesh.points.max(axis=0)
    gap = np.maximum(np.maximum(-high, low - (np.asarray(grid.dimensions) - 1) * spacing), 0.0)
    reach_limit = diagonal + float(np.linalg.norm(gap)) + max(spacing)
    slack = _slack(grid)
    reach = min(band_mm, reach_limit) + slack
    tri_kind = mesh.degenerate.astype(np.int64)
    if regions == "box":
        tri_kind[:] = 1
        wedges, wedge_vertices = np.empty((0, 13)), np.empty((0, 3), dtype=np.int64)
        cone_info, cone_start = np.empty((0, 3), dtype=np.int64), np.zeros((1, 2), dtype=np.int64)
        cone_rays, cone_edges = np.empty((0, 3)), np.empty((0, 3))
    else:
        mesh.with_topology()
        edges, edge_start, edge_faces, vertex_start, vertex_faces, _ = mesh.topology
        wedges, wedge_vertices = characteristics.edge_wedges(mesh.points, mesh.triangles, mesh.degenerate, edges,
                                                             edge_start, edge_faces, reach, slack)
        cone_info, cone_start, cone_rays, cone_edges = characteristics.vertex_cones(
            mesh.points, mesh.triangles, mesh.degenerate, vertex_start, vertex_faces)
    report(progress, 0.05)
    m = len(mesh.triangles)
    n_regions = m + len(wedges) + len(cone_info)
    first = np.empty(n_regions, dtype=np.int64)
    last = np.empty(n_regions, dtype=np.int64)
    args = (m, tri_kind, mesh.frames, mesh.frame_vertices, mesh.points, wedges, wedge_vertices, cone_info,
            cone_start, cone_rays, cone_edges, reach, slack)
    kernels.polytope_slices(n_regions, *args, spacing[2], nz, first, last)
    slab = max(1, min(8, nz // 32))
    n_slabs = (nz + slab - 1) // slab
    spans = np.where(last >= first, last // slab - first // slab + 1, 0)
    entries = int(spans.sum())
    if entries > MAX_SLICE_ENTRIES:
        raise ValueError(f"a band of {band_mm:g} mm needs {entries:,} slab-region pairs ({entries * 4 / 2**30:.1f} "
                         "GiB of work lists); choose a narrower band or use --outside propagate")
    slab_start, members = scan.slab_lists(first, last, slab, n_slabs)
    report(progress, 0.1)
    busy = np.flatnonzero(np.diff(slab_start) > 0)
    counts = np.zeros((n_slabs, 2), dtype=np.int64)
    if busy.size:
        # a few calls of similar work (for progress); inside each, the heaviest slabs first and handed out one at
        # a time, so both threads stay busy to the end
        slab_work = np.diff(slab_start)[busy]
        work = np.cumsum(slab_work)
        chunks = max(1, min(4, busy.size // 8))
        bounds = np.searchsorted(work, np.linspace(0, work[-1], chunks + 1)[1:-1], side="right")
        done = 0
        with numba.parallel_chunksize(1):
            for part, part_work in zip(np.split(busy, bounds), np.split(slab_work, bounds)):
                if part.size == 0:
                    continue
                order = part[np.argsort(-part_work, kind="stable")].astype(np.int64)
                scan.scan_slabs(order, slab, slab_start, members, *args, spacing, distance2, nearest, counts)
                done += part.size
                report(progress, 0.1 + 0.9 * done / busy.size)
    report(progress, 1.0)
    stats = {"regions": int(n_regions), "prisms_or_boxes": int(m), "wedges": int(len(wedges)),
             "cones": int(len(cone_info)), "slab_region_pairs": entries, "evaluations": int(counts[:, 0].sum()),
             "lines": int(counts[:, 1].sum()), "seconds": time.perf_counter() - start_time}
    return BandDistances(distance2, nearest, band_mm, stats)


def exact_distances(points, triangles, samples, *, chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """Distances (mm) from each sample point ``(q, 3)`` to the mesh and a nearest triangle, by brute force over all
    triangles (the reference of the tests and benchmarks; O(q m))."""
    points = np.asarray(points, np.float64)
    triangles = np.ascontiguousarray(triangles, np.int64)
    m = len(triangles)
    frames = np.empty((m, kernels.FRAME_SIZE))
    kernels.triangle_frames(points, triangles, frames, np.empty((m, 3), np.int64), np.empty(m, np.int64),
                            np.empty(m, np.bool_))
    samples = np.ascontiguousarray(samples, np.float64).reshape(-1, 3)
    out2 = np.empty(len(samples))
    nearest = np.empty(len(samples), dtype=np.int64)
    for s in range(0, len(samples), chunk):
        kernels.distances_to_mesh(frames, samples[s:s + chunk], out2[s:s + chunk], nearest[s:s + chunk])
    return np.sqrt(out2), nearest


def band_from_percent(points, grid: Grid, percent: float) -> float:
    """A band width in mm: ``percent`` of the mesh's extent along the grid's k axis (source 002's table 3.1 gives
    bands in per cent of the model's z extent)."""
    percent = float(percent)
    if not (percent > 0 and math.isfinite(percent)):
        raise ValueError(f"the band must be a positive percentage, got {percent}")
    heights = (np.asarray(points, np.float64) - np.asarray(grid.origin)) @ grid.direction_matrix[:, 2]
    height = float(heights.max() - heights.min()) if len(heights) else 0.0
    if height <= 0:
        raise ValueError("the mesh has no extent along the grid's k axis, so a band in per cent is undefined; "
                         "give it in mm")
    return percent / 100.0 * height


@dataclass
class DistanceField:
    """A signed distance field on ``grid``: ``values`` (float32 mm, ``(nz, ny, nx)``, negative inside), ``nearest``
    (int32 index of a nearest triangle, -1 where none: outside the band with ``outside="clamp"``), the band width,
    the rule used outside it, and ``seconds`` (``sign``, ``band``, ``outside``, ``total``) and ``stats``."""

    values: np.ndarray
    nearest: np.ndarray
    grid: Grid
    band_mm: float
    outside: str
    seconds: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @property
    def value_range(self) -> tuple[float, float]:
        return float(self.values.min()), float(self.values.max())


def signed_distance(points, triangles, grid: Grid, *, band_mm: float, outside: str = "clamp",
                    inside: str = "parity", regions: str = "characteristic",
                    progress: ProgressCallback = None) -> DistanceField:
    """The signed distance field (mm, negative inside) of a closed triangle mesh on ``grid``.

    Parameters
    ----------
    points, triangles : ndarray
        The mesh (``(n, 3)`` LPS mm and ``(m, 3)`` point indices; shared edges share their indices).
    grid : Grid
        Target grid (any spacing, origin and rotation).
    band_mm : float
        Width d of the exact band (mm). Every voxel within d of the mesh gets its exact distance.
    outside : {"clamp", "propagate"}
        Outside the band: ``+-d`` (clamp), or the distance to a triangle found by nearest-triangle propagation
        (:mod:`.propagate`: never below the true distance, exact wherever the voxel's nearest triangle is reached).
    inside : {"parity", "winding"}
        The voxelisation rule that gives the sign (:func:`algorithms.fields.voxelise.voxelise`); never a plane or normal test.
    regions : {"characteristic", "box"}
        Region scanned per triangle (:func:`band_distances`).
    progress : callable, optional
        Called with the fraction done; may raise :class:`~algorithms.common.progress.OperationCancelled`.

    Returns
    -------
    DistanceField
        ``values`` float32 ``(nz, ny, nx)``; negative where the voxelisation mask is 1, positive or zero elsewhere.

    Raises
    ------
    ValueError
        Bad mesh, grid, band, rule; a mesh without triangles.
    """
    if outside not in OUTSIDE_RULES:
        raise ValueError(f"outside must be one of {', '.join(OUTSIDE_RULES)}, got {outside!r}")
    points, triangles = _validated(points, triangles, grid)
    if len(triangles) == 0:
        raise ValueError("the mesh has no triangles, so it has no distance field")
    band_mm = float(band_mm)
    if not band_mm > 0:
        raise ValueError(f"the band width must be a positive number of mm, got {band_mm}")
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    tick = start
    mask = voxelise(points, triangles, grid, inside=inside, progress=scaled(progress, 0.0, 0.15))
    seconds["sign"] = time.perf_counter() - tick
    tick = time.perf_counter()
    mesh = MeshFrames.build(points, triangles, grid)
    band_end = 0.75 if outside == "propagate" else 0.95
    band = band_distances(points, triangles, grid, band_mm, regions=regions, mesh=mesh,
                          progress=scaled(progress, 0.15, band_end))
    seconds["band"] = time.perf_counter() - tick
    tick = time.perf_counter()
    distance2, nearest = band.distance2, band.nearest
    stats = dict(band.stats)
    if outside == "propagate":
        stats.update(propagate(distance2, nearest, mesh, grid.spacing, band_mm, progress=scaled(progress, band_end,
                                                                                                  0.95)))
        values = np.sqrt(distance2, out=distance2)
    else:
        values = np.sqrt(distance2, out=distance2)
        np.minimum(values, np.float32(band_mm), out=values)
    np.negative(values, out=values, where=mask.astype(bool))
    seconds["outside"] = time.perf_counter() - tick
    seconds["total"] = time.perf_counter() - start
    report(progress, 1.0)
    stats["inside_voxels"] = int(np.count_nonzero(mask))
    return DistanceField(values, nearest, grid, band_mm, outside, seconds, stats)
