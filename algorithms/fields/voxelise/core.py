"""Mesh voxelisation: a closed triangle mesh to a binary mask on any grid, slice by slice and row by row.

Method (source 002, section 2.2)
--------------------------------
Source 002 voxelises a closed, oriented mesh on the GPU one slice at a time: a clip plane at the slice, the back
faces drawn, then the front faces drawn over them, so what remains in the frame buffer is the cross-section. This
is the same idea on the CPU, as a scan conversion: for each slice ``k`` and each row ``j`` of the slice (the line
through the voxel centres ``(i, j, k)`` along ``i``), the crossings of the row with the mesh are found and the
voxels between them filled, by parity (odd number of crossings before the voxel: inside). Triangles are sorted
into the slices their bounding box meets, each triangle is tested only against the rows its box covers, and the
slices run in parallel (numba); no Python loop over voxels or triangles. See :mod:`.kernels`.

Exactness
---------
Rows pass exactly through vertices and edges all the time (a cube aligned with the grid, a marching-cubes mesh
voxelised on its own grid). The row-triangle test uses exact orientation signs (Shewchuk's adaptive predicate) and
simulation of simplicity, the convention of :func:`algorithms.compare.topology.ray_crossings`: the row is moved
by ``(e, e^2)`` in ``(j, k)`` and each edge is judged once, from its lower to its higher vertex index. A row then
crosses exactly one triangle of each sheet of surface at a shared edge or vertex, whatever the rounding, so a
closed mesh gives an even number of crossings in every row. A voxel counts a crossing at ``x`` when ``x <= i``
(the centre moved by ``+e'`` along ``i``), so a centre exactly on the surface is decided deterministically. The
crossing's position along the row is interpolated in floating point: a centre within about 1e-12 voxels of the
surface may fall either way, but always the same way for the same input. Vertices are mapped to the index frame
rounded to multiples of 2^-30 voxel, so a vertex meant to lie on a voxel centre or boundary (a mesh made on the
grid, seen through a rotated or scaled grid) lands there exactly; nothing moves by more than 1e-9 voxel.

Inside rules
------------
``"parity"`` (default, source 002's rule): odd crossings before the voxel. Needs a closed mesh (every edge used by
an even number of triangles); nested shells, cavities and touching pieces are all handled by parity, and the
orientation does not matter. On an open mesh a row through a hole has an odd number of crossings and fills to
the end of the grid: check the mesh first (:func:`algorithms.compare.topology.edge_manifoldness`).

``"winding"``: inside where the generalised winding number (Jacobson et al. 2013) is at least 1/2, the solid a
user expects of a mesh with small holes or self-intersections; needs outward-facing triangles. Computed exactly
in two parts: every piece of the boundary is closed by a fan (:func:`algorithms.fields.winding.boundary_caps`), the signed row
crossings of mesh plus fans give the integer winding number ``n`` of the closed chain, and ``w = n - w_caps``.
Where the caps' winding number is bounded below 1/2 (``|w_cap| <= area / (4 pi d^2)`` at distance ``d``), ``w >=
1/2`` exactly when ``n >= 1``; only the voxels near the caps are evaluated by the hierarchical far-field
approximation of Barill et al. (2018), :class:`algorithms.fields.winding.WindingTree`. On a closed, outward mesh there are no caps
and winding and parity agree voxel for voxel.

Frames and array order
----------------------
Points are ``(x, y, z)`` LPS mm; the grid (:class:`algorithms.common.grid.Grid`, any spacing, origin and rotation)
maps them to its index frame once, ``(p - origin) @ direction / spacing``, and all tests run there. The mask has
the grid's NumPy shape ``(nz, ny, nx)``, indexed ``[k, j, i]``.

References
----------
Source 002 (German MSc thesis "Vergleich von Volumenmodellen", see docs/references.md), section 2.2
"Konvertierung von Dreiecksnetzen", after the slicing voxelisation described by Engel, Hadwiger, Kniss,
Rezk-Salama and Weiskopf, "Real-Time Volume Graphics", 2006, and Fang and Chen, "Hardware accelerated
voxelization", 2000.
J. R. Shewchuk, "Adaptive precision floating-point arithmetic and fast robust geometric predicates", 1997.
H. Edelsbrunner, E. P. Mücke, "Simulation of simplicity", ACM Transactions on Graphics 9(1), 1990.
A. Jacobson, L. Kavan, O. Sorkine-Hornung, "Robust inside-outside segmentation using generalized winding numbers",
2013; G. Barill et al., "Fast winding numbers for soups and clouds", 2018 (see :mod:`.winding`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numba
import numpy as np

from ...common.grid import Grid
from ...common.progress import ProgressCallback, report, scaled
from . import kernels

__all__ = ["INSIDE_RULES", "VoxelisationReport", "voxelise", "voxelise_with_report", "warm_up"]

#: The inside rules :func:`voxelise` offers.
INSIDE_RULES = ("parity", "winding")
#: Share of 1/2 the caps' winding number may reach outside the voxels evaluated by the tree (the rest is margin).
_CAP_BUDGET = 0.45
#: Allowance for the error of the fans' far-field expansion when a cube of voxels is skipped.
_MARGIN = 0.02
#: Below this much work (triangles + voxels / 8) one thread does it: starting the others costs more than they save,
#: and far more on a busy machine, where every start waits for each thread's time slice.
_SMALL_JOB = 1_000_000


@dataclass(frozen=True)
class VoxelisationReport:
    """What one voxelisation did.

    Attributes
    ----------
    rule : str
        ``"parity"`` or ``"winding"``.
    crossings : int
        Row-surface crossings found (fans included).
    caps : int
        Boundary pieces closed by a fan (winding rule; 0 for a closed mesh).
    boundary_edges : int
        Boundary edges those fans close, with multiplicity.
    tree_voxels : int
        Voxels near the fans whose winding number the tree evaluated.
    seconds : float
        Wall time of the whole voxelisation (s).
    """

    rule: str
    crossings: int
    caps: int = 0
    boundary_edges: int = 0
    tree_voxels: int = 0
    seconds: float = 0.0

    def describe(self) -> dict:
        return {"rule": self.rule, "crossings": self.crossings, "caps": self.caps,
                "boundary_edges": self.boundary_edges, "tree_voxels": self.tree_voxels, "seconds": self.seconds}


def _validated(points, triangles, grid, inside) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be an algorithms.common.grid.Grid, got {type(grid).__name__}")
    if inside not in INSIDE_RULES:
        raise ValueError(f"inside must be one of {', '.join(INSIDE_RULES)}, got {inside!r}")
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3 or points.dtype.kind not in "iuf":
        raise ValueError(f"points must be an (n, 3) array of real coordinates, got {points.dtype} {points.shape}")
    points = np.ascontiguousarray(points, dtype=np.float64)
    if not np.all(np.isfinite(points)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(points), axis=1)))
        raise ValueError(f"{bad} of {len(points)} points have NaN or infinite coordinates")
    triangles = np.asarray(triangles)
    if triangles.size == 0:
        triangles = triangles.reshape(0, 3)
    if triangles.ndim != 2 or triangles.shape[1] != 3 or triangles.dtype.kind not in "iu":
        raise ValueError(f"triangles must be an (m, 3) array of point indices, got {triangles.dtype} "
                         f"{triangles.shape}")
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    if triangles.size and (triangles.min() < 0 or triangles.max() >= len(points)):
        raise ValueError(f"triangle corners must be point indices in [0, {len(points)}), got "
                         f"{int(triangles.min())}..{int(triangles.max())}")
    return points, triangles


def voxelise(points, triangles, grid: Grid, *, inside: str = "parity",
             progress: ProgressCallback = None) -> np.ndarray:
    """Voxelise a closed triangle mesh: 1 where a voxel centre of ``grid`` is inside (see the module notes).

    Parameters
    ----------
    points : ndarray (n, 3)
        Vertex positions ``(x, y, z)``, LPS mm.
    triangles : ndarray (m, 3) of int
        Vertex indices; triangles sharing an edge must share its two indices (merge duplicate points first).
    grid : Grid
        Target grid (dimensions, spacing, origin, direction; anisotropic and rotated grids work).
    inside : {"parity", "winding"}
        Inside rule: parity of row crossings (closed meshes), or generalised winding number >= 1/2 (meshes with
        holes or self-intersections, outward-facing).
    progress : callable, optional
        Called with the fraction done; raising :class:`~algorithms.common.progress.OperationCancelled` cancels.

    Returns
    -------
    ndarray (nz, ny, nx) of uint8
        ``grid.shape``; 1 inside, 0 outside.

    Raises
    ------
    ValueError
        If the points are not finite ``(n, 3)`` coordinates, a triangle names a missing point, ``grid`` is not a
        :class:`Grid` or ``inside`` is not a known rule.

    Examples
    --------
    >>> grid = Grid.around(bounds, voxels=256)
    >>> mask = voxelise(points, triangles, grid)
    >>> volume_mm3 = mask.sum() * grid.voxel_volume
    """
    return voxelise_with_report(points, triangles, grid, inside=inside, progress=progress)[0]


def voxelise_with_report(points, triangles, grid: Grid, *, inside: str = "parity", beta: float = 2.0,
                         progress: ProgressCallback = None) -> tuple[np.ndarray, VoxelisationReport]:
    """:func:`voxelise`, also returning a :class:`VoxelisationReport`; ``beta`` is the far-field criterion of the
    winding tree (:meth:`algorithms.fields.winding.WindingTree.winding_numbers`)."""
    start = time.perf_counter()
    points, triangles = _validated(points, triangles, grid, inside)
    mask = np.zeros(grid.shape, dtype=np.uint8)
    if len(triangles) == 0:
        report(progress, 1.0)
        return mask, VoxelisationReport(inside, 0, seconds=time.perf_counter() - start)
    all_points, all_triangles = points, triangles
    caps = None
    if inside == "winding":
        from ..winding import boundary_caps  # here: SciPy's sparse graphs load only for the winding rule

        caps = boundary_caps(points, triangles)
        if caps.count:
            all_points, all_triangles = caps.points, np.concatenate([triangles, caps.triangles])
    threads = numba.get_num_threads()
    if len(all_triangles) + grid.size // 8 < _SMALL_JOB:
        numba.set_num_threads(1)  # this thread's later launches only (numba keeps the setting per thread)
    try:
        return _voxelise(grid, inside, points, triangles, all_points, all_triangles, caps, mask, beta, start,
                         progress)
    finally:
        numba.set_num_threads(threads)


def _voxelise(grid, inside, points, triangles, all_points, all_triangles, caps, mask, beta, start, progress):
    index_points = np.empty_like(all_points)
    matrix = np.ascontiguousarray(grid.direction_matrix / np.asarray(grid.spacing)[None, :])
    kernels.index_points(all_points, np.asarray(grid.origin, dtype=np.float64), matrix, index_points)
    handedness = 1 if np.linalg.det(grid.direction_matrix) > 0 else -1
    winding = inside == "winding"
    near = winding and caps.count > 0
    # The kernel fills an int8 view under both rules (parity writes 1s, the mask's own bytes), so it is compiled
    # once; winding: it writes the closed chain's integer winding number, which is then thresholded.
    target = mask.view(np.int8)
    crossings = _fill(index_points, all_triangles, target, winding=winding, handedness=handedness,
                      progress=scaled(progress, 0.0, 0.6 if near else 1.0))
    tree_voxels = 0
    if near:  # levels become 0/1 where the fans' winding number may reach 1/2
        tree_voxels = _near_caps(grid, caps, target, beta, progress=scaled(progress, 0.6, 1.0))
    if winding:
        np.greater_equal(target, 1, out=mask.view(np.bool_))  # in place, element by element
    report(progress, 1.0)
    return mask, VoxelisationReport(
        inside, crossings, caps=caps.count if caps is not None else 0,
        boundary_edges=caps.edges if caps is not None else 0, tree_voxels=tree_voxels,
        seconds=time.perf_counter() - start)


def warm_up() -> float:
    """Load every kernel (from numba's cache, or compile it) by voxelising a small open box by both rules; returns
    the seconds it took, so callers can report the voxelisation's own time apart from it."""
    start = time.perf_counter()
    corners = np.array([[x, y, z] for z in (0.5, 2.5) for y in (0.5, 2.5) for x in (0.5, 2.5)])
    quads = ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5))
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    grid = Grid((4, 4, 4))
    voxelise(corners, triangles, grid)
    voxelise(corners, triangles[1:], grid, inside="winding")
    return time.perf_counter() - start


def _fill(index_points, triangles, mask, *, winding: bool, handedness: int, progress) -> int:
    """Row crossings and filling, slice chunks in turn (progress between chunks)."""
    nz, ny, nx = mask.shape
    rows = np.empty((len(triangles), 4), dtype=np.int64)
    kernels.triangle_rows(index_points, triangles, ny, nz, rows)
    offsets, members = kernels.slice_buckets(rows, nz)
    busy = np.flatnonzero(np.diff(offsets) > 0)
    crossings = 0
    if busy.size == 0:
        return 0
    # Chunks of similar work (triangle-slice pairs plus voxels to fill), so progress moves evenly; a chunk's slices
    # run in parallel. Each chunk is one start of numba's threads (on a busy machine each start can wait for a
    # time slice), so small jobs take few chunks, and a call without a progress callback takes one.
    work = np.cumsum(np.diff(offsets)[busy] + ny * nx // 8)
    chunks = 1 if progress is None else int(np.clip(work[-1] // 250_000, 1, min(16, max(1, busy.size // 2))))
    bounds = np.searchsorted(work, np.linspace(0, work[-1], chunks + 1)[1:-1], side="right")
    done = 0
    for part in np.split(busy, bounds):
        if part.size == 0:
            continue
        found = kernels.fill_slices(index_points, triangles, rows, offsets, members, part.astype(np.int64), mask,
                                    winding, handedness)
        crossings += int(found.sum())
        done += part.size
        report(progress, done / busy.size)
    return crossings


#: Edge of the cubes of voxels the fans' winding number is examined in (split down to single voxels near them).
_BLOCK = 16


def _cap_blocks(grid: Grid, centre: np.ndarray, reach: float) -> np.ndarray:
    """The ``_BLOCK``-aligned cubes of voxels ``(i0, j0, k0)`` meeting the ball of ``reach`` mm around ``centre``."""
    spacing = np.asarray(grid.spacing)
    middle = grid.world_to_index(centre)
    dims = np.asarray(grid.dimensions)
    low = np.clip(np.floor(middle - reach / spacing), 0, dims - 1).astype(np.int64) // _BLOCK
    high = np.clip(np.ceil(middle + reach / spacing), 0, dims - 1).astype(np.int64) // _BLOCK
    if np.any(middle + reach / spacing < 0) or np.any(middle - reach / spacing > dims - 1):
        return np.empty((0, 3), dtype=np.int64)
    axes = [np.arange(lo, hi + 1) for lo, hi in zip(low, high)]
    cubes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * _BLOCK
    # keep the cubes whose nearest voxel centre lies within reach (lengths are kept by the rotation)
    nearest = np.clip(middle, cubes, np.minimum(cubes + _BLOCK - 1, dims - 1))
    close = np.linalg.norm((nearest - middle) * spacing, axis=1) <= reach
    return cubes[close]


def _near_caps(grid: Grid, caps, levels, beta: float, *, progress) -> int:
    """Threshold ``levels - w_caps`` at 1/2 wherever the fans' winding number ``w_caps`` may reach 1/2.

    Outside a ball of ``radius + sqrt(area / (4 pi budget))`` around each fan, ``|w| <= area / (4 pi d^2)`` keeps
    each fan's share below ``budget``; inside, cubes of voxels are examined from coarse to fine
    (:func:`algorithms.fields.winding.blocks.threshold_blocks`). Returns the voxels decided one by one.
    """
    from ..winding import WindingTree  # here: SciPy's sparse graphs load only for the winding rule
    from ..winding.blocks import threshold_blocks

    budget = _CAP_BUDGET / caps.count  # each cap's share: the sum over all caps stays below 1/2 elsewhere
    reaches = caps.radius + np.sqrt(caps.area / (4.0 * math.pi * budget))
    cubes = [_cap_blocks(grid, centre, reach) for centre, reach in zip(caps.centre, reaches)]
    cubes = np.unique(np.concatenate(cubes), axis=0)
    if len(cubes) == 0:
        return 0
    blocks = np.column_stack([cubes, np.full(len(cubes), _BLOCK)]).astype(np.int64)
    tree = WindingTree.build(caps.points, caps.triangles)
    by_cap = np.argsort(caps.piece, kind="stable")
    rims = np.ascontiguousarray(caps.triangles[by_cap, :2])
    rim_start = np.searchsorted(caps.piece[by_cap], np.arange(caps.count + 1)).astype(np.int64)
    evaluated = np.zeros(len(blocks), dtype=np.int64)
    chunk = max(1, -(-len(blocks) // 16))
    for start in range(0, len(blocks), chunk):
        stop = min(start + chunk, len(blocks))
        threshold_blocks(*tree.arrays(), rims, rim_start, caps.centre, caps.radius, caps.length, float(beta),
                         grid.affine, levels, blocks[start:stop], _MARGIN, evaluated[start:stop])
        report(progress, stop / len(blocks))
    return int(evaluated.sum())

