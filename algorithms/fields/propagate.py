"""Filling the grid outside the exact band: nearest-triangle propagation, so every far voxel still measures its
distance to a real triangle of the mesh.

Method
------
Source 002 (section 3.3) proposes to fill the space its band leaves out by propagating from the exact band values.
Propagating distance *values* (fast marching, fast sweeping of the eikonal equation, a distance transform of the
band) accumulates discretisation error; here, as in vector or closest-point propagation (Danielsson 1980; Mauch
2003; the closest-triangle sweeps of Batty's SDFGen), what travels is the index of a nearest triangle, and every
voxel measures its own exact distance to each candidate it is offered, keeping the smallest:

1. sweeps along i, j and k, forwards and backwards (each line in parallel): every voxel outside the band is
   offered the triangle of the voxel before it, so every voxel holds some triangle;
2. a descent on the mesh from each voxel's triangle: if the point of that triangle nearest to the voxel lies on an
   edge or at a vertex (the source's regions II-VI), the triangles sharing that edge or vertex are tried, and the
   voxel moves to a nearer one until none is nearer;
3. jump flooding (Rong and Tan 2006): each voxel is offered the triangles of the 26 voxels ``s`` away, for ``s`` =
   half the grid's largest side, halved down to 1, which carries triangles across thin parts and around corners
   that the sweeps and the descent miss;
4. rounds of (26-neighbour offers + descent) until a round changes no voxel (at most ``passes``).

Values are compared as stored (float32), so every accepted offer strictly lowers a voxel's value and the rounds end.

Error bound
-----------
A propagated value is the distance to a real triangle, so it is never below the true distance ``D``: the error
``e = value - D >= 0``. It is zero where the voxel's nearest triangle reaches it (through the sweeps or the descent:
a nearest triangle on the same sheet of surface as a candidate is always found by the descent, whose distance
along the sheet has no other local minimum). When a neighbour ``w`` (at ``|v - w| <= h``, ``h`` the largest voxel
diagonal step) holds its exact nearest triangle, ``e(v) <= 2 |v - w|``, since ``dist(v, T_w) <= D(w) + |v - w|
<= D(v) + 2 |v - w|``; a voxel can only miss its nearest triangle when that triangle's region of nearest points
(its Voronoi cell) passes between the voxel centres around it, that is near the medial axis where two sheets are
equally far, and there the error is the difference of two nearly equal distances. The benchmark and the tests
measure it against exact distances (``voxelscope bench distance``: at most 0.05 voxels at 10,000 random far
voxels is required; SDFGen reaches 0.084).

Coordinates: the grid's frame in mm, voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)``; arrays ``(nz, ny, nx)``.

References
----------
Source 002 (see docs/references.md), section 3.3 (combining the exact band with propagation).
P.-E. Danielsson, "Euclidean distance mapping", Computer Graphics and Image Processing 14, 1980.
S. Mauch, "Efficient algorithms for solving static Hamilton-Jacobi equations", PhD thesis, Caltech, 2003.
G. Rong, T.-S. Tan, "Jump flooding in GPU with applications to Voronoi diagram and distance transform", I3D 2006.
C. Batty, SDFGen (closest-triangle fast sweeping), https://github.com/christopherbatty/SDFGen.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..common.progress import ProgressCallback, report
from ._distance_kernels import frame_feature, point_triangle_distance2

__all__ = ["propagate"]

#: Mesh steps of the descent before it gives up (each step is strictly nearer, so it ends anyway).
MAX_STEPS = 64


@njit(cache=True, nogil=True)
def _offer(best, nearest, k, j, i, candidate, frames, x, y, z, band2):
    if candidate < 0 or candidate == nearest[k, j, i] or best[k, j, i] <= band2:
        return False
    d2 = np.float32(point_triangle_distance2(frames, candidate, x, y, z))
    if d2 < best[k, j, i]:  # compared as stored (float32): strictly decreasing, so passes end
        best[k, j, i] = d2
        nearest[k, j, i] = candidate
        return True
    return False


@njit(cache=True, nogil=True, parallel=True)
def sweep_rows(best, nearest, frames, spacing, band2):
    """Forwards and backwards along i, every row in parallel."""
    nz, ny, nx = best.shape
    for k in prange(nz):
        z = k * spacing[2]
        for j in range(ny):
            y = j * spacing[1]
            for i in range(1, nx):
                _offer(best, nearest, k, j, i, nearest[k, j, i - 1], frames, i * spacing[0], y, z, band2)
            for i in range(nx - 2, -1, -1):
                _offer(best, nearest, k, j, i, nearest[k, j, i + 1], frames, i * spacing[0], y, z, band2)


@njit(cache=True, nogil=True, parallel=True)
def sweep_columns(best, nearest, frames, spacing, band2):
    """Forwards and backwards along j, every slice in parallel."""
    nz, ny, nx = best.shape
    for k in prange(nz):
        z = k * spacing[2]
        for j in range(1, ny):
            y = j * spacing[1]
            for i in range(nx):
                _offer(best, nearest, k, j, i, nearest[k, j - 1, i], frames, i * spacing[0], y, z, band2)
        for j in range(ny - 2, -1, -1):
            y = j * spacing[1]
            for i in range(nx):
                _offer(best, nearest, k, j, i, nearest[k, j + 1, i], frames, i * spacing[0], y, z, band2)


@njit(cache=True, nogil=True, parallel=True)
def sweep_slices(best, nearest, frames, spacing, band2):
    """Forwards and backwards along k, every column (fixed j) in parallel."""
    nz, ny, nx = best.shape
    for j in prange(ny):
        y = j * spacing[1]
        for k in range(1, nz):
            z = k * spacing[2]
            for i in range(nx):
                _offer(best, nearest, k, j, i, nearest[k - 1, j, i], frames, i * spacing[0], y, z, band2)
        for k in range(nz - 2, -1, -1):
            z = k * spacing[2]
            for i in range(nx):
                _offer(best, nearest, k, j, i, nearest[k + 1, j, i], frames, i * spacing[0], y, z, band2)


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
            g = faces[q]
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
            vertex_faces, spacing, band2, moved):
    """The mesh descent of every voxel outside the band, slices in parallel; ``moved[k]`` counts the voxels of slice
    ``k`` that found a nearer triangle."""
    nz, ny, nx = best.shape
    for k in prange(nz):
        z = k * spacing[2]
        count = 0
        for j in range(ny):
            y = j * spacing[1]
            for i in range(nx):
                if best[k, j, i] <= band2:
                    continue
                if _descend(best, nearest, k, j, i, frames, frame_vertices, rotation, triangle_edges, edge_start,
                            edge_faces, vertex_start, vertex_faces, i * spacing[0], y, z):
                    count += 1
        moved[k] = count


def propagate(best: np.ndarray, nearest: np.ndarray, mesh, spacing, band_mm: float, *, passes: int = 8,
              progress: ProgressCallback = None) -> dict:
    """Fill ``best`` (squared mm, float32) and ``nearest`` (int32) outside the band, in place (see the module notes).

    ``mesh`` is a :class:`.distance.MeshFrames`; voxels with ``best <= band_mm**2`` are exact and kept. One round of
    sweeps along the three axes, a mesh descent, jump-flooding offers at steps ``2^p ... 1``, then up to ``passes``
    rounds of (26-neighbour offers + descent), stopping as soon as a round changes no voxel. Returns counts for the
    report.
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    band2 = np.float32(band_mm) ** 2 if np.isfinite(band_mm) else np.float32(np.inf)
    frames = mesh.frames
    jumps = []
    step = 1 << max(0, int(np.log2(max(best.shape))) - 1)
    while step >= 1:
        jumps.append(step)
        step //= 2
    steps = 4 + len(jumps) + passes
    done = 0
    for sweep in (sweep_rows, sweep_columns, sweep_slices):
        sweep(best, nearest, frames, spacing, band2)
        done += 1
        report(progress, done / steps)
    mesh.with_topology()
    _, edge_start, edge_faces, vertex_start, vertex_faces, triangle_edges = mesh.topology
    moved = np.zeros(best.shape[0], dtype=np.int64)
    changed = np.zeros(best.shape[0], dtype=np.int64)

    def descent() -> int:
        moved[:] = 0
        descend(best, nearest, frames, mesh.frame_vertices, mesh.rotation, triangle_edges, edge_start, edge_faces,
                vertex_start, vertex_faces, spacing, band2, moved)
        return int(moved.sum())

    def offers(jump: int) -> int:
        changed[:] = 0
        neighbourhood(best, nearest, nearest.copy(), frames, spacing, band2, changed, jump)
        return int(changed.sum())

    total_moves = descent()
    done += 1
    report(progress, done / steps)
    for jump in jumps:
        offers(jump)
        done += 1
        report(progress, done / steps)
    changed_per_pass = []
    for _ in range(passes):
        count = offers(1)
        count += descent()
        changed_per_pass.append(count)
        done += 1
        report(progress, done / steps)
        if count == 0:
            break
    report(progress, 1.0)
    return {"jump_steps": jumps, "changes_per_pass": changed_per_pass}


@njit(cache=True, nogil=True, parallel=True)
def neighbourhood(best, nearest, source, frames, spacing, band2, changed, step=1):
    """Every voxel outside the band is offered the triangles of its 26 neighbours ``step`` voxels away in ``source``
    (a copy of ``nearest`` from before the pass); ``changed[k]`` counts the voxels of slice ``k`` that took one."""
    nz, ny, nx = best.shape
    for k in prange(nz):
        z = k * spacing[2]
        count = 0
        tried = np.empty(27, dtype=np.int64)  # the distinct triangles offered to this voxel so far
        for j in range(ny):
            y = j * spacing[1]
            for i in range(nx):
                if best[k, j, i] <= band2:
                    continue
                x = i * spacing[0]
                n_tried = 0
                for dk in range(-step, step + 1, step):
                    kk = k + dk
                    if kk < 0 or kk >= nz:
                        continue
                    for dj in range(-step, step + 1, step):
                        jj = j + dj
                        if jj < 0 or jj >= ny:
                            continue
                        for di in range(-step, step + 1, step):
                            ii = i + di
                            if ii < 0 or ii >= nx:
                                continue
                            candidate = source[kk, jj, ii]
                            seen = False
                            for q in range(n_tried):
                                if tried[q] == candidate:
                                    seen = True
                                    break
                            if seen:
                                continue
                            tried[n_tried] = candidate
                            n_tried += 1
                            if _offer(best, nearest, k, j, i, candidate, frames, x, y, z, band2):
                                count += 1
        changed[k] = count
