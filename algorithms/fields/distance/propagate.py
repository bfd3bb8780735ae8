"""Filling the grid outside the exact band: every far voxel measures its exact distance to candidate triangles
handed to it by a Euclidean feature transform of the band (or by the same propagation on every second voxel), then
checks its neighbours' triangles.

Method
------
Source 002 (section 3.3) proposes to fill the space its band leaves out by propagating from the exact band values.
Propagating distance *values* (fast marching, fast sweeping, a distance transform of the band) accumulates
discretisation error; here, as in closest-point propagation (Danielsson 1980; Mauch 2003; the closest-triangle
sweeps of Batty's SDFGen), what travels is the index of a nearest triangle, and every voxel measures its own exact
distance to each candidate it is offered, keeping the smallest:

1. **candidates**: on a grid of fewer than :data:`COARSE_FROM` voxels along some axis, the exact separable Euclidean
   distance transform of Felzenszwalb and Huttenlocher (2012; the lower envelope of parabolas, as in Meijster et al.
   2000; :mod:`.feature_transform`), one pass per axis with the grid's own (possibly anisotropic) spacing, every
   line in parallel, gives every voxel its *nearest band voxel* ``w`` (exact, ties aside), and the voxel measures its
   distance to ``w``'s nearest triangle (O(N)). On larger grids the whole propagation runs first on every second
   voxel (recursively), and each voxel measures the triangles of the (up to 8) coarse voxels around it; a voxel whose
   coarse neighbours all hold one triangle is taken as settled and skips step 2 and the first round of step 3 (a
   heuristic: the regions of nearest points are close to convex at the scale of a cell, but not exactly, since their
   borders are curved where an edge or a vertex faces a face; the measured errors include it);
2. **mesh descent**: if the point of the voxel's triangle nearest to it lies on an edge or at a vertex (the source's
   regions II-VI), the triangles sharing that edge or vertex are tried, and the voxel moves to a nearer one until
   none is nearer;
3. **local check**: a first round, in parallel, in which each voxel next to a voxel still to check (or, on the
   finer levels, to a band voxel) is offered the triangles of those of its 26 neighbours, then a worklist: every
   voxel that took a new triangle offers it to its 26 neighbours, and a neighbour that takes it descends from it and
   joins the list, until the list is empty (two slabs at once, one thread each, then the voxels at the cut between
   them; :func:`settle`). Every voxel examined ends nearer to its own triangle than to its neighbours' and to the
   triangles next to its own nearest edge or vertex.

Values are compared as stored (float32), so every accepted offer strictly lowers a voxel's value and the rounds end.

Threads: each parallel pass is one region of one iteration per thread, in which the threads take slices one at a
time from a shared counter (:func:`algorithms.common.atomics.take`): the voxels still to check crowd into some
slices, and a split fixed in advance would leave a thread waiting.

Error bound
-----------
A propagated value is the distance to a real triangle, so it is never below the true distance ``D``: the error
``e = value - D >= 0``. Before the checks: let ``p`` be the voxel's nearest mesh point; the point of the segment
from ``v`` to ``p`` at ``d - h sqrt(3) / 2`` from ``p`` (``d`` the band width, ``h`` the largest spacing, ``d >= h
sqrt(3)``) has a voxel ``u`` within ``h sqrt(3) / 2`` that is in the band, so the nearest band voxel ``w`` has
``|v - w| <= |v - u| <= D - d + h sqrt(3)``, and ``e <= |v - w| + D(w) - D <= h sqrt(3)``. From a coarse level,
a coarse voxel ``c`` within ``h sqrt(3) / 2`` of ``v`` gives ``e(v) <= e(c) + 2 |v - c| <= e(c) + h sqrt(3)``. These
a priori bounds are loose: when ``w`` lies on the segment, ``T_w`` is the voxel's own nearest triangle (every point
of the segment has the same nearest point), so ``e`` comes only from ``w``'s offset from the segment (within about
half a voxel) and from curvature of the mesh between the two nearest points, which the descent and the local check
remove wherever the distance along the mesh has one minimum; what remains is near the medial axis, where two sheets
are nearly equally far and the error is the difference of two nearly equal distances. The benchmark and the tests
measure it against exact distances (at most 0.05 voxels at 10,000 random far voxels is required; SDFGen reaches 0.084).

Coordinates: the grid's frame in mm, voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)``; arrays ``(nz, ny, nx)``.

References
----------
Source 002 (see docs/references.md), section 3.3 (combining the exact band with propagation).
P. F. Felzenszwalb, D. P. Huttenlocher, "Distance transforms of sampled functions", Theory of Computing 8, 2012.
A. Meijster, J. B. T. M. Roerdink, W. H. Hesselink, "A general algorithm for computing distance transforms in
linear time", Mathematical Morphology and its Applications to Image and Signal Processing, 2000.
P.-E. Danielsson, "Euclidean distance mapping", Computer Graphics and Image Processing 14, 1980.
S. Mauch, "Efficient algorithms for solving static Hamilton-Jacobi equations", PhD thesis, Caltech, 2003.
C. Batty, SDFGen (closest-triangle fast sweeping), https://github.com/christopherbatty/SDFGen.
"""

from __future__ import annotations

import time

import numpy as np
from numba import get_num_threads, njit, prange

from ...common.atomics import take
from ...common.progress import ProgressCallback, report, scaled
from .kernels import frame_feature, point_triangle_distance2
from .feature_transform import feature_columns, feature_rows, feature_slices

__all__ = ["propagate"]

#: Mesh steps of the descent before it gives up (each step is strictly nearer, so it ends anyway).
MAX_STEPS = 64


@njit(cache=True, nogil=True, inline="always")
def _already_tried(tried, n_tried, candidate) -> bool:
    """Whether ``candidate`` is among the first ``n_tried`` entries of ``tried`` (a voxel's short candidate list)."""
    for r in range(n_tried):
        if tried[r] == candidate:
            return True
    return False


@njit(cache=True, nogil=True)
def _offer(best, nearest, k, j, i, candidate, frames, x, y, z, band2):
    """Offer triangle ``candidate`` to voxel ``(k, j, i)`` at ``(x, y, z)`` mm; True when it is nearer. Callers pass
    ``candidate`` as int64 (read from int32 arrays): numba compiles this, and the distance, once per argument type."""
    if candidate < 0 or candidate == nearest[k, j, i] or best[k, j, i] <= band2:
        return False
    d2 = np.float32(point_triangle_distance2(frames, candidate, x, y, z))
    if d2 < best[k, j, i]:  # compared as stored (float32): strictly decreasing, so passes end
        best[k, j, i] = d2
        nearest[k, j, i] = candidate
        return True
    return False


@njit(cache=True, nogil=True, parallel=True)
def offer_sites(best, nearest, site, frames, spacing, band2, parts):
    """Every voxel outside the band measures its distance to the triangle of its nearest band voxel ``site`` (the
    feature transform's flat index) and keeps it if nearer; slices in parallel."""
    nz, ny, nx = best.shape
    flat_nearest = nearest.reshape(-1)
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # k taken from a shared counter (module notes)
        while True:
            k = take(queue, 1)
            if k >= nz:
                break
            z = k * spacing[2]
            for j in range(ny):
                y = j * spacing[1]
                for i in range(nx):
                    target = site[k, j, i]
                    if best[k, j, i] <= band2 or target < 0:
                        continue
                    candidate = np.int64(flat_nearest[target])  # a band voxel's: never written here
                    _offer(best, nearest, k, j, i, candidate, frames, i * spacing[0], y, z, band2)


@njit(cache=True, nogil=True, inline="always")
def _gather_column(nearest, was, k0, k1, j0, j1, i, columns) -> int:
    """The distinct triangles of the voxels marked in ``was`` among the (up to 9) voxels ``(k0:k1, j0:j1, i)`` into
    ``columns[i]``; returns how many."""
    n = 0
    for kk in range(k0, k1):
        for jj in range(j0, j1):
            if was[kk, jj, i]:
                candidate = nearest[kk, jj, i]
                seen = False
                for r in range(n):
                    if columns[i, r] == candidate:
                        seen = True
                        break
                if not seen:
                    columns[i, n] = candidate
                    n += 1
    return n


@njit(cache=True, nogil=True, parallel=True)
def refine_round(best, nearest, frames, frame_vertices, rotation, triangle_edges, edge_start, edge_faces,
                 vertex_start, vertex_faces, spacing, band2, was, now, rows_was, rows_now, changed, coarse, parts):
    """The parallel first round of the local check: every voxel outside the band next to a voxel marked in ``was``
    (per voxel; ``rows_was``, per row ``(k, j)``) is offered the triangles of those of its 26 neighbours and
    descends from a better one; voxels that take one are marked in ``now`` / ``rows_now`` (where :func:`settle`
    starts). ``changed[k]`` counts them per slice.

    A row's neighbour triangles are gathered once per column of 3 x 3 voxels (each column serves three voxels of
    the row), before the row is visited; a neighbour updated in this round is marked in ``now`` and offers its new
    triangle in the worklist. The triangles a voxel already measured, its own and (on a finer level, ``coarse`` of
    more than one voxel) those of the coarse voxels around it that :func:`from_coarse` offered, are not measured
    again: each thread stamps a triangle with the flat index of the voxel that measured it last (a lookup in place
    of a search through the voxel's list)."""
    nz, ny, nx = best.shape
    cz, cy, cx = coarse.shape
    from_coarser = coarse.size > 1
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # k taken from a shared counter (module notes)
        columns = np.empty((nx, 9), dtype=np.int64)
        in_column = np.empty(nx, dtype=np.int64)
        stamp = np.full(frames.shape[0], -1, dtype=np.int64)  # stamp[t] == v: voxel v measured triangle t
        while True:
            k = take(queue, 1)
            if k >= nz:
                break
            z = k * spacing[2]
            k0, k1 = max(k - 1, 0), min(k + 2, nz)
            count = 0
            for j in range(ny):
                j0, j1 = max(j - 1, 0), min(j + 2, ny)
                active = False
                for kk in range(k0, k1):
                    for jj in range(j0, j1):
                        active |= rows_was[kk, jj]
                if not active:
                    continue
                for i in range(nx):
                    in_column[i] = _gather_column(nearest, was, k0, k1, j0, j1, i, columns)
                y = j * spacing[1]
                row_count = 0
                for i in range(nx):
                    if best[k, j, i] <= band2:
                        continue
                    v = (k * ny + j) * nx + i
                    if nearest[k, j, i] >= 0:
                        stamp[nearest[k, j, i]] = v
                    coarse_listed = not from_coarser
                    took = False
                    x = i * spacing[0]
                    for ii in range(max(i - 1, 0), min(i + 2, nx)):
                        for r in range(in_column[ii]):
                            candidate = columns[ii, r]
                            if candidate < 0 or stamp[candidate] == v:
                                continue
                            if not coarse_listed:  # listed only when some neighbour offers something new
                                coarse_listed = True
                                for q in range(8):
                                    other = coarse[min((k + (q & 1)) // 2, cz - 1),
                                                   min((j + ((q >> 1) & 1)) // 2, cy - 1),
                                                   min((i + (q >> 2)) // 2, cx - 1)]
                                    if other >= 0:
                                        stamp[other] = v
                                if stamp[candidate] == v:
                                    continue
                            stamp[candidate] = v
                            if _offer(best, nearest, k, j, i, candidate, frames, x, y, z, band2):
                                took = True
                    if took:
                        _descend(best, nearest, k, j, i, frames, frame_vertices, rotation, triangle_edges, edge_start,
                                 edge_faces, vertex_start, vertex_faces, x, y, z)
                        now[k, j, i] = True
                        row_count += 1
                if row_count:
                    rows_now[k, j] = True
                    count += row_count
            changed[k] = count


@njit(cache=True, nogil=True)
def _descend(best, nearest, k, j, i, frames, frame_vertices, rotation, triangle_edges, edge_start, edge_faces,
             vertex_start, vertex_faces, x, y, z):
    current = nearest[k, j, i]
    if current < 0:
        return 0
    d2 = best[k, j, i]  # float32, as stored
    moves = 0
    for _ in range(MAX_STEPS):
        dx = x - frames[current, 0]
        dy = y - frames[current, 1]
        dz = z - frames[current, 2]
        r = dx * frames[current, 3] + dy * frames[current, 4] + dz * frames[current, 5]
        s = dx * frames[current, 6] + dy * frames[current, 7] + dz * frames[current, 8]
        feature = frame_feature(r, s, frames[current, 12], frames[current, 13], frames[current, 14])
        if feature == 0:
            break
        if feature <= 3:
            e = triangle_edges[current, (rotation[current] + feature - 1) % 3]
            first, last = edge_start[e], edge_start[e + 1]
            faces = edge_faces
        else:
            v = frame_vertices[current, feature - 4]
            first, last = vertex_start[v], vertex_start[v + 1]
            faces = vertex_faces
        chosen = current
        for q in range(first, last):
            g = np.int64(faces[q])
            if g == current:
                continue
            dg = np.float32(point_triangle_distance2(frames, g, x, y, z))
            if dg < d2:
                d2 = dg
                chosen = g
        if chosen == current:
            break
        current = chosen
        moves += 1
    if moves:
        best[k, j, i] = d2
        nearest[k, j, i] = current
    return moves


@njit(cache=True, nogil=True, parallel=True)
def descend(best, nearest, frames, frame_vertices, rotation, triangle_edges, edge_start, edge_faces, vertex_start,
            vertex_faces, spacing, band2, parts):
    """The mesh descent of every voxel outside the band, slices in parallel (the coarsest level's; on finer levels
    :func:`from_coarse` descends as it goes)."""
    nz, ny, nx = best.shape
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # k taken from a shared counter (module notes)
        while True:
            k = take(queue, 1)
            if k >= nz:
                break
            z = k * spacing[2]
            for j in range(ny):
                y = j * spacing[1]
                for i in range(nx):
                    if best[k, j, i] > band2:
                        _descend(best, nearest, k, j, i, frames, frame_vertices, rotation, triangle_edges,
                                 edge_start, edge_faces, vertex_start, vertex_faces, i * spacing[0], y, z)


@njit(cache=True, nogil=True, parallel=True)
def from_coarse(best, nearest, coarse, frames, frame_vertices, rotation, triangle_edges, edge_start, edge_faces,
                vertex_start, vertex_faces, spacing, band2, marks, rows, parts):
    """Every voxel outside the band is offered the triangles of the (up to 8) voxels of the half-resolution grid
    ``coarse`` (voxel ``(i, j, k)`` there is voxel ``(2i, 2j, 2k)`` here) around it; a voxel offered more than one
    triangle descends on the mesh from the best (while its triangle's frame is still in cache) and is marked in
    ``marks`` (per voxel) and ``rows`` (per row)."""
    nz, ny, nx = best.shape
    cz, cy, cx = coarse.shape
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # k taken from a shared counter (module notes)
        tried = np.empty(8, dtype=np.int64)
        while True:
            k = take(queue, 1)
            if k >= nz:
                break
            z = k * spacing[2]
            for j in range(ny):
                y = j * spacing[1]
                for i in range(nx):
                    if best[k, j, i] <= band2:
                        continue
                    x = i * spacing[0]
                    n_tried = 0
                    for q in range(8):
                        candidate = np.int64(coarse[min((k + (q & 1)) // 2, cz - 1),
                                                    min((j + ((q >> 1) & 1)) // 2, cy - 1),
                                                    min((i + (q >> 2)) // 2, cx - 1)])
                        if _already_tried(tried, n_tried, candidate):
                            continue
                        tried[n_tried] = candidate
                        n_tried += 1
                        _offer(best, nearest, k, j, i, candidate, frames, x, y, z, band2)
                    if n_tried > 1:
                        _descend(best, nearest, k, j, i, frames, frame_vertices, rotation, triangle_edges, edge_start,
                                 edge_faces, vertex_start, vertex_faces, x, y, z)
                        marks[k, j, i] = True
                        rows[k, j] = True


@njit(cache=True, nogil=True)
def settle(best, nearest, frames, frame_vertices, rotation, triangle_edges, edge_start, edge_faces, vertex_start,
           vertex_faces, spacing, band2, start, queued, k_lo, k_hi, owed):
    """The rest of the local check as one worklist, in order: every voxel in the list (first: ``start``, flat
    indices of the voxels the first round changed; ``queued`` marks them) offers its triangle to its 26
    neighbours outside the band; a neighbour that takes it descends from it and joins the list. Ends when the list
    is empty (every accepted offer strictly lowers a stored value). Returns the number of voxels changed.

    Only the voxels of slices ``k_lo <= k < k_hi`` (a slab) are offered anything, so two slabs can settle at once
    without touching each other's voxels; a voxel of the slab's first or last slice that offers while a slab lies
    beyond is marked in ``owed``: it still owes those offers."""
    nz, ny, nx = best.shape
    owes_below = k_lo > 0
    owes_above = k_hi < nz
    capacity = max(1024, 2 * start.shape[0])
    queue = np.empty(capacity, dtype=np.int64)
    queue[:start.shape[0]] = start
    head = 0
    size = start.shape[0]
    changes = 0
    while size:
        v = queue[head]
        head = (head + 1) % capacity
        size -= 1
        i = v % nx
        j = (v // nx) % ny
        k = v // (nx * ny)
        queued[k, j, i] = False
        if (owes_below and k == k_lo) or (owes_above and k == k_hi - 1):
            owed[k, j, i] = True
        candidate = np.int64(nearest[k, j, i])
        for q in range(27):
            ii = i + q % 3 - 1
            jj = j + (q // 3) % 3 - 1
            kk = k + q // 9 - 1
            if q == 13 or ii < 0 or ii >= nx or jj < 0 or jj >= ny or kk < k_lo or kk >= k_hi:
                continue
            x, y, z = ii * spacing[0], jj * spacing[1], kk * spacing[2]
            if not _offer(best, nearest, kk, jj, ii, candidate, frames, x, y, z, band2):
                continue
            _descend(best, nearest, kk, jj, ii, frames, frame_vertices, rotation, triangle_edges, edge_start,
                     edge_faces, vertex_start, vertex_faces, x, y, z)
            changes += 1
            if queued[kk, jj, ii]:
                continue
            if size == capacity:  # grow, keeping the order
                bigger = np.empty(2 * capacity, dtype=np.int64)
                for r in range(size):
                    bigger[r] = queue[(head + r) % capacity]
                queue = bigger
                capacity *= 2
                head = 0
            queue[(head + size) % capacity] = (kk * ny + jj) * nx + ii
            queued[kk, jj, ii] = True
            size += 1
    return changes



@njit(cache=True, nogil=True, parallel=True)
def settle_slabs(best, nearest, frames, frame_vertices, rotation, triangle_edges, edge_start, edge_faces,
                 vertex_start, vertex_faces, spacing, band2, start, split, cut, queued, owed, changes):
    """:func:`settle` on the slabs below and from slice ``cut``, one thread each: ``start[:split]`` and
    ``start[split:]`` (sorted flat indices) are their lists; ``changes[0 or 1]`` their counts. The voxels next to
    the cut that still owe offers across it are marked in ``owed``."""
    nz = best.shape[0]
    bottom = np.int64(0)  # not a literal 0: numba would compile settle for it as well as for int64
    for part in prange(2):
        if part == 0:
            changes[0] = settle(best, nearest, frames, frame_vertices, rotation, triangle_edges, edge_start,
                                edge_faces, vertex_start, vertex_faces, spacing, band2, start[:split], queued, bottom,
                                cut, owed)
        else:
            changes[1] = settle(best, nearest, frames, frame_vertices, rotation, triangle_edges, edge_start,
                                edge_faces, vertex_start, vertex_faces, spacing, band2, start[split:], queued, cut, nz,
                                owed)


#: Grids at least this large along every axis start from a half-resolution propagation.
COARSE_FROM = 96


def _settle_in_two(best, nearest, frames, topology, spacing, band2, now) -> int:
    """The worklist of the local check from the voxels marked in ``now`` (cleared on the way): two slabs, split
    where half the voxels to start from lie on each side, settle at once (one thread each); then the voxels next
    to the cut that owe offers across it start one last worklist over the whole grid. Returns the changes."""
    nz, ny, nx = best.shape
    start = np.flatnonzero(now.reshape(-1))
    owed = np.zeros(best.shape, dtype=np.bool_)
    changes = 0
    if len(start) >= 2 and nz >= 4:
        cut = int(min(max(start[len(start) // 2] // (nx * ny), 1), nz - 1))
        split = int(np.searchsorted(start, cut * nx * ny))
        counts = np.zeros(2, dtype=np.int64)
        settle_slabs(best, nearest, frames, *topology, spacing, band2, start, split, cut, now, owed, counts)
        changes += int(counts.sum())
        start = np.flatnonzero(owed.reshape(-1))
    else:
        owed |= now
    changes += settle(best, nearest, frames, *topology, spacing, band2, start, owed, np.int64(0), nz, owed)
    return changes


def propagate(best: np.ndarray, nearest: np.ndarray, mesh, spacing, band_mm: float, *,
              progress: ProgressCallback = None) -> dict:
    """Fill ``best`` (squared mm, float32) and ``nearest`` (int32) outside the band, in place (see the module notes).

    ``mesh`` is a :class:`.core.MeshFrames`; voxels with ``best <= band_mm**2`` (and a triangle) are exact and
    kept. Each voxel outside the band first gets candidate triangles: on a grid of at least :data:`COARSE_FROM`
    voxels along every axis (and a band at least a quarter of the doubled spacing), those of the propagation on
    every second voxel (recursively); otherwise the triangle of its nearest band voxel (the feature transform).
    Then the mesh descent and the local check (one parallel round, then the worklist until nothing changes).
    Returns counts (``changes_per_pass``: voxels still to check, changed by the first round, by the worklist) and
    seconds for the report (``candidates``, coarser levels and the descent included; ``first_round``;
    ``worklist``).
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    band2 = np.float32(band_mm) ** 2 if np.isfinite(band_mm) else np.float32(np.inf)
    if best.size >= np.iinfo(np.int32).max:
        raise ValueError(f"a grid of {best.size:,} voxels is too large for propagation (at most 2^31 - 1)")
    start = time.perf_counter()
    parts = get_num_threads()  # the parallel passes' threads, each taking slices from a shared counter
    frames = mesh.frames
    mesh.with_topology()
    _, edge_start, edge_faces, vertex_start, vertex_faces, triangle_edges = mesh.topology
    topology = (mesh.frame_vertices, mesh.rotation, triangle_edges, edge_start, edge_faces, vertex_start,
                vertex_faces)
    seeds = best <= band2
    seeds &= nearest >= 0
    n_seeds = int(np.count_nonzero(seeds))
    del seeds
    levels = 1
    # the voxels still to check (descent, first round of the local check): all, or those whose coarse neighbours
    # disagree (a cell whose 8 coarse corners share a triangle lies in that triangle's region, which is convex)
    todo = np.zeros(best.shape, dtype=np.bool_)
    rows_todo = np.zeros(best.shape[:2], dtype=np.bool_)
    if min(best.shape) >= COARSE_FROM and 2.0 * max(spacing) <= 4.0 * band_mm:
        coarse_best = np.ascontiguousarray(best[::2, ::2, ::2])
        coarse = np.ascontiguousarray(nearest[::2, ::2, ::2])
        inner = propagate(coarse_best, coarse, mesh, 2.0 * spacing, band_mm,
                          progress=scaled(progress, 0.0, 0.3))
        del coarse_best
        levels += inner["levels"]
        from_coarse(best, nearest, coarse, frames, *topology, spacing, band2, todo, rows_todo, parts)
        # the band's own triangles are offered to the voxels next to it (the coarse level has only every second)
        in_band = best <= band2
        todo |= in_band
        rows_todo |= in_band.any(axis=2)
        del in_band
    else:
        if n_seeds == 0:
            # no voxel within the band: seed the grid's centre voxel with its exact nearest triangle (brute force)
            from .kernels import distances_to_mesh

            k, j, i = (n // 2 for n in best.shape)
            out2, which = np.empty(1), np.empty(1, dtype=np.int64)
            distances_to_mesh(frames, np.array([[i * spacing[0], j * spacing[1], k * spacing[2]]]), out2, which)
            best[k, j, i] = min(best[k, j, i], np.float32(out2[0]))
            nearest[k, j, i] = which[0]
            band2 = min(band2, best[k, j, i])
        work = np.empty(best.shape, dtype=np.float32)
        site = np.empty(best.shape, dtype=np.int32)
        feature_rows(best, band2, spacing[0], work, site, parts)
        feature_columns(work, site, spacing[1], parts)
        feature_slices(work, site, spacing[2], parts)
        offer_sites(best, nearest, site, frames, spacing, band2, parts)
        del work, site
        todo[:] = True
        rows_todo[:] = True
        descend(best, nearest, frames, *topology, spacing, band2, parts)
        coarse = np.zeros((1, 1, 1), dtype=nearest.dtype)  # no coarser level whose offers the first round can skip
    timing = {"candidates": time.perf_counter() - start}
    report(progress, 0.5)
    changed_per_pass = [int(np.count_nonzero(todo))]
    # the first round of the local check looks next to every voxel still to check; later rounds only next to the
    # voxels that changed
    now = np.zeros(best.shape, dtype=np.bool_)
    rows_now = np.zeros(best.shape[:2], dtype=np.bool_)
    changed = np.zeros(best.shape[0], dtype=np.int64)
    tick = time.perf_counter()
    refine_round(best, nearest, frames, *topology, spacing, band2, todo, now, rows_todo, rows_now, changed, coarse,
                 parts)
    changed_per_pass.append(int(changed.sum()))
    timing["first_round"] = time.perf_counter() - tick
    del todo, rows_todo, coarse
    report(progress, 0.7)
    tick = time.perf_counter()
    changed_per_pass.append(_settle_in_two(best, nearest, frames, topology, spacing, band2, now))
    timing["worklist"] = time.perf_counter() - tick
    report(progress, 1.0)
    return {"seed_voxels": n_seeds, "levels": levels, "changes_per_pass": changed_per_pass,
            "propagation_seconds": timing}
