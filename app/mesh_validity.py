"""The validity report of an exported surface, lean enough for meshes of millions of triangles, with progress.

It answers what :func:`app.mesh_cleanup.validity_report` promises - watertight, manifold, outward, pieces, area
and enclosed volume - with the definitions of :mod:`algorithms.compare.topology` (edges shared by an even number
of triangles close a surface; a vertex is pinched when its triangles form more than one fan; a closed piece faces
outward when its signed volume is positive at even nesting depth and negative at odd depth), and gives the same
answers (``tests/app/test_mesh_validity.py`` checks it against those functions on random, voxel, pinched, nested
and real meshes). What differs is the cost: every array is built once and dropped as soon as it has served
(about 100 bytes per triangle at the peak instead of about 450), geometry is summed in blocks of triangles instead
of one ``(m, 3, 3)`` float64 array, the nesting test looks only at the pieces whose bounding box can hold a probe,
and each step reports progress, so a long report shows where it is and can be cancelled (the progress callback
raises :class:`~algorithms.common.progress.OperationCancelled`).

Arrays: points ``(n, 3)`` (x, y, z) mm, triangles ``(m, 3)`` vertex indices, counter-clockwise seen from the side
they face (VTK's convention).
"""

from __future__ import annotations

import time

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.compare.topology import EdgeReport, ray_crossings

#: Triangles per block when summing areas and volumes (a block's float64 corners take 72 bytes per triangle: 18 MB).
BLOCK = 1 << 18


def _index_type(count: int):
    return np.int32 if count < 2**31 - 1 else np.int64


def _edge_pairs(points_count: int, tris: np.ndarray):
    """Group the 3m directed edge occurrences by undirected edge.

    Returns the per-edge occurrence counts and direction sums (occurrences from the lower to the higher vertex
    index count +1, the others -1), the odd edges' vertex pairs, and the pairs of occurrences of the edges used by
    exactly two triangles (occurrence ``o`` is edge ``o % 3`` of triangle ``o // 3``).
    """
    start = tris.reshape(-1)
    end = tris[:, [1, 2, 0]].reshape(-1)
    low = np.minimum(start, end)
    key = low * np.int64(max(points_count, 1))
    key += np.maximum(start, end)
    forward = start < end
    del start, end, low
    order = np.argsort(key, kind="stable")
    key = key[order]
    boundaries = np.flatnonzero(np.diff(key)) + 1
    firsts = np.concatenate(([0], boundaries))
    counts = np.diff(np.concatenate((firsts, [key.size])))
    unique_keys = key[firsts]
    del key, boundaries
    direction = np.where(forward[order], 1, -1).astype(np.int8)
    direction_sum = np.add.reduceat(direction, firsts, dtype=np.int64)
    del direction
    odd_keys = unique_keys[counts % 2 == 1]
    del unique_keys
    odd_vertices = np.stack([odd_keys // max(points_count, 1), odd_keys % max(points_count, 1)], axis=1)
    # Occurrences of edges used exactly twice, as (first, second) in sorted order.
    twice = np.flatnonzero(counts == 2)
    pairs = np.stack([order[firsts[twice]], order[firsts[twice] + 1]], axis=1)
    same_direction = forward[pairs[:, 0]] == forward[pairs[:, 1]]
    return counts, direction_sum, odd_vertices, pairs, same_direction


def _pinched_vertices(tris: np.ndarray, pairs: np.ndarray, same_direction: np.ndarray) -> int:
    """Vertices around which the triangle corners form more than one edge-connected fan (the rule of
    :func:`algorithms.compare.topology.edge_manifoldness`)."""
    if len(tris) == 0:
        return 0
    corners = 3 * len(tris)
    index = _index_type(corners)
    first, second = pairs[:, 0], pairs[:, 1]
    start1, end1 = first % 3, (first + 1) % 3
    start2, end2 = second % 3, (second + 1) % 3
    base1 = (first - start1).astype(index)
    base2 = (second - start2).astype(index)
    # Corners meet across the shared edge: the start of one occurrence is the start of the other when both run the
    # same way, else its end.
    rows = np.concatenate([base1 + start1, base1 + end1]).astype(index, copy=False)
    cols = np.concatenate([base2 + np.where(same_direction, start2, end2),
                           base2 + np.where(same_direction, end2, start2)]).astype(index, copy=False)
    del base1, base2, start1, end1, start2, end2
    graph = sparse.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(corners, corners))
    del rows, cols
    _, labels = connected_components(graph, directed=False)
    del graph
    fans = tris.reshape(-1).astype(np.int64) * np.int64(corners)
    fans += labels
    del labels
    fans = np.unique(fans)  # one entry per (vertex, fan), sorted by vertex
    vertices = fans // corners
    del fans
    starts = np.flatnonzero(np.concatenate(([True], vertices[1:] != vertices[:-1])))
    fans_per_vertex = np.diff(np.concatenate((starts, [vertices.size])))
    return int(np.count_nonzero(fans_per_vertex > 1))


def edge_report(points_count: int, tris: np.ndarray, progress: ProgressCallback = None):
    """:class:`~algorithms.compare.topology.EdgeReport` of a triangle mesh, and the vertex pairs of its odd edges."""
    if len(tris) == 0:
        report(progress, 1.0)
        return EdgeReport(0, 0, 0, 0, 0, 0), np.empty((0, 2), dtype=np.int64)
    counts, direction_sum, odd_vertices, pairs, same_direction = _edge_pairs(points_count, tris)
    report(progress, 0.5)
    even = counts % 2 == 0
    result = EdgeReport(
        edges=int(counts.size),
        boundary_edges=int(np.count_nonzero(counts == 1)),
        nonmanifold_edges=int(np.count_nonzero(counts > 2)),
        inconsistent_edges=int(np.count_nonzero(even & (direction_sum != 0))),
        nonmanifold_vertices=0,
        odd_edges=int(np.count_nonzero(~even)),
    )
    del counts, direction_sum, even
    pinched = _pinched_vertices(tris, pairs, same_direction)
    report(progress, 1.0)
    return EdgeReport(**{**result.__dict__, "nonmanifold_vertices": pinched}), odd_vertices


def _labels(points_count: int, tris: np.ndarray):
    """Vertex-connected pieces: the number of pieces with triangles, each triangle's piece and each point's piece
    (-1 for points no triangle uses)."""
    index = _index_type(points_count)
    rows = tris.reshape(-1).astype(index)
    cols = tris[:, [1, 2, 0]].reshape(-1).astype(index)
    graph = sparse.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(points_count, points_count))
    del rows, cols
    _, labels = connected_components(graph, directed=False)
    del graph
    used = np.zeros(points_count, dtype=bool)
    used[tris.reshape(-1)] = True
    pieces, point_piece = np.unique(np.where(used, labels, -1), return_inverse=True)
    point_piece = point_piece.astype(np.int64) - (1 if pieces[0] == -1 else 0)  # unused points -> -1
    count = pieces.size - (1 if pieces[0] == -1 else 0)
    return count, point_piece[tris[:, 0]], point_piece


def _geometry(points: np.ndarray, tris: np.ndarray, triangle_piece: np.ndarray, count: int, used: np.ndarray,
              progress: ProgressCallback):
    """Total area (mm^2) and the signed volume of each piece (mm^3), summed in blocks of triangles.

    Volumes are taken about the centre of the used points' bounding box, as
    :func:`algorithms.compare.measures.signed_volumes` does (better rounding, same total).
    """
    centre = 0.5 * (points[used].min(axis=0).astype(np.float64) + points[used].max(axis=0))
    area = 0.0
    volumes = np.zeros(count)
    for begin in range(0, len(tris), BLOCK):
        block = tris[begin:begin + BLOCK]
        p0 = points[block[:, 0]] - centre
        p1 = points[block[:, 1]] - centre
        p2 = points[block[:, 2]] - centre
        area += 0.5 * float(np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1).sum())
        volumes += np.bincount(triangle_piece[begin:begin + BLOCK], weights=np.einsum("ij,ij->i", p0,
                               np.cross(p1, p2)) / 6.0, minlength=count)
        report(progress, min(1.0, (begin + BLOCK) / len(tris)))
    return area, volumes


def _nesting_depth(points: np.ndarray, tris: np.ndarray, triangle_piece: np.ndarray, point_piece: np.ndarray,
                   closed: np.ndarray, progress: ProgressCallback) -> np.ndarray:
    """How many other closed pieces enclose each closed piece (the rule of
    :func:`algorithms.compare.topology.orientation_outward`: a probe inside the first triangle of each closed piece
    is tested by exact ray crossings against every other closed piece whose bounding box holds it)."""
    count = closed.size
    depth = np.zeros(count, dtype=np.int64)
    closed_ids = np.flatnonzero(closed)
    if closed_ids.size < 2:
        report(progress, 1.0)
        return depth
    order = np.argsort(triangle_piece, kind="stable")
    starts = np.searchsorted(triangle_piece[order], np.arange(count + 1))
    low = np.full((count, 3), np.inf)
    high = np.full((count, 3), -np.inf)
    used = point_piece >= 0
    np.minimum.at(low, point_piece[used], points[used])
    np.maximum.at(high, point_piece[used], points[used])
    probes = points[tris[order[starts[closed_ids]]]].astype(np.float64).mean(axis=1)
    by_x = np.argsort(probes[:, 0], kind="stable")
    probe_x = probes[by_x, 0]
    last = time.perf_counter()
    for number, outer in enumerate(closed_ids):
        first = np.searchsorted(probe_x, low[outer, 0], "right")
        stop = np.searchsorted(probe_x, high[outer, 0], "left")
        if stop > first:
            candidates = by_x[first:stop]
            inside = np.all((probes[candidates] > low[outer]) & (probes[candidates] < high[outer]), axis=1)
            candidates = candidates[inside & (closed_ids[candidates] != outer)]
            if candidates.size:
                piece = tris[order[starts[outer]:starts[outer + 1]]]
                vertices, local = np.unique(piece, return_inverse=True)
                crossings = ray_crossings(points[vertices], local.reshape(-1, 3), probes[candidates])
                depth[closed_ids[candidates][crossings % 2 == 1]] += 1
        if progress is not None and (number % 16 == 15 or time.perf_counter() - last > 0.1):
            last = time.perf_counter()
            report(progress, (number + 1) / closed_ids.size)
    report(progress, 1.0)
    return depth


def validity_numbers(points: np.ndarray, tris: np.ndarray, *, progress: ProgressCallback = None) -> dict:
    """Everything the validity report says about a triangle mesh, as a dict: ``edges`` (an
    :class:`~algorithms.compare.topology.EdgeReport`), ``components``, ``volumes`` and ``closed`` per piece,
    ``depth`` per piece, ``outward``, ``area_mm2`` and ``volume_mm3`` (signed, of the whole mesh)."""
    points = np.asarray(points)
    if points.dtype not in (np.float32, np.float64):
        points = points.astype(np.float64)
    tris = np.asarray(tris)
    if tris.dtype.kind not in "iu":
        raise ValueError(f"triangles must be integer vertex indices, got {tris.dtype}")
    tris = tris.astype(np.int64, copy=False).reshape(-1, 3)
    n = points.shape[0]
    if len(tris) == 0:
        report(progress, 1.0)
        return {"edges": EdgeReport(0, 0, 0, 0, 0, 0), "components": 0, "volumes": np.zeros(0),
                "closed": np.zeros(0, bool), "depth": np.zeros(0, np.int64), "outward": True, "area_mm2": 0.0,
                "volume_mm3": 0.0}
    edges, odd_vertices = edge_report(n, tris, scaled(progress, 0.0, 0.45))
    count, triangle_piece, point_piece = _labels(n, tris)
    report(progress, 0.6)
    closed = np.ones(count, dtype=bool)
    closed[np.unique(point_piece[odd_vertices[:, 0]])] = False
    del odd_vertices
    area, volumes = _geometry(points, tris, triangle_piece, count, point_piece >= 0, scaled(progress, 0.6, 0.75))
    depth = _nesting_depth(points, tris, triangle_piece, point_piece, closed, scaled(progress, 0.75, 1.0))
    expected = np.where(depth % 2 == 0, 1.0, -1.0)
    outward = bool(np.all(np.sign(volumes[closed]) == expected[closed]))
    return {"edges": edges, "components": count, "volumes": volumes, "closed": closed, "depth": depth,
            "outward": outward, "area_mm2": area, "volume_mm3": float(volumes.sum())}
