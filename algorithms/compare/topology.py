"""The topology of triangle surfaces: edges, manifoldness, closedness, pieces, orientation, inside tests.

- :func:`edge_manifoldness` (:class:`EdgeReport`), :func:`is_watertight`, :func:`is_manifold`,
  :func:`connected_components`.
- :func:`orientation_outward` (:class:`OrientationReport`): do the triangles of every closed piece face away from
  the solid, counting nesting (a surface around a cavity, such as the inner table of a skull, faces into the
  cavity, away from the solid, and encloses a *negative* volume).
- :func:`ray_crossings`: exact ray-surface crossing counts by simulation of simplicity, the inside test of
  closed surfaces (also for mesh voxelisation).

Surfaces in any form :func:`algorithms.compare.triangles.surface_arrays` accepts.

References
----------
H. Edelsbrunner, E. P. Mücke, "Simulation of simplicity: a technique to cope with degenerate cases in geometric
algorithms", ACM Transactions on Graphics 9(1), 1990. doi:10.1145/77635.77639.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components as _graph_components

from .measures import signed_volumes
from .triangles import surface_arrays

__all__ = [
    "EdgeReport",
    "OrientationReport",
    "connected_components",
    "edge_manifoldness",
    "is_manifold",
    "is_watertight",
    "orientation_outward",
    "ray_crossings",
]


@dataclass(frozen=True)
class EdgeReport:
    """Edge and vertex topology of a triangle mesh.

    Attributes
    ----------
    edges : int
        Distinct undirected edges.
    boundary_edges : int
        Edges used by one triangle (the rim of a hole or of an open surface).
    nonmanifold_edges : int
        Edges used by three or more triangles.
    inconsistent_edges : int
        Edges shared by an even number of triangles that do not traverse it as often in one direction as in the
        other (the winding flips across it).
    nonmanifold_vertices : int
        Vertices whose triangles form more than one fan (surfaces touching at a point).
    odd_edges : int
        Edges used by an odd number of triangles: the rim of a hole (one triangle) or a fin (three, five, ...).
    """

    edges: int
    boundary_edges: int
    nonmanifold_edges: int
    inconsistent_edges: int
    nonmanifold_vertices: int
    odd_edges: int

    @property
    def watertight(self) -> bool:
        """Closed: every edge is shared by an even number of triangles.

        Two on a manifold surface; four where two solids touch along an edge, as voxel surfaces do where voxels meet
        only diagonally. Such a surface is closed (it encloses a volume) but not manifold, which :attr:`manifold`
        reports.
        """
        return self.edges > 0 and self.odd_edges == 0

    @property
    def manifold(self) -> bool:
        """No edge with more than two triangles and no pinched vertex (boundaries are allowed)."""
        return self.nonmanifold_edges == 0 and self.nonmanifold_vertices == 0

    @property
    def consistently_oriented(self) -> bool:
        return self.inconsistent_edges == 0


@dataclass
class _Edges:
    """Per-triangle-edge occurrences grouped by undirected edge (internal)."""

    key: np.ndarray  # (3m,) undirected key per occurrence
    forward: np.ndarray  # (3m,) True if the occurrence runs from the lower to the higher vertex index
    unique_keys: np.ndarray
    inverse: np.ndarray  # occurrence -> unique edge
    counts: np.ndarray  # unique edge -> number of occurrences
    order: np.ndarray = field(repr=False)  # occurrences sorted by key


def _edges(points_count: int, tris: np.ndarray) -> _Edges:
    start = tris.reshape(-1)
    end = tris[:, [1, 2, 0]].reshape(-1)
    low, high = np.minimum(start, end), np.maximum(start, end)
    key = low * np.int64(max(points_count, 1)) + high
    order = np.argsort(key, kind="stable")
    unique_keys, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    return _Edges(key, start < end, unique_keys, inverse, counts, order)


def _nonmanifold_vertices(tris: np.ndarray, edges: _Edges) -> int:
    """Vertices around which the triangle corners form more than one edge-connected fan."""
    if len(tris) == 0:
        return 0
    occurrence_count = edges.counts[edges.inverse]
    sorted_occurrences = edges.order[occurrence_count[edges.order] == 2].reshape(-1, 2)  # pairs sharing an edge
    first, second = sorted_occurrences[:, 0], sorted_occurrences[:, 1]
    # Occurrence o is edge o % 3 of triangle o // 3, from corner o % 3 to corner (o + 1) % 3.
    tri1, tri2 = first // 3, second // 3
    start1, end1 = first % 3, (first + 1) % 3
    start2, end2 = second % 3, (second + 1) % 3
    same_direction = edges.forward[first] == edges.forward[second]
    # Match corners by vertex: the start of one occurrence is the start of the other if they run the same way.
    partner_of_start1 = np.where(same_direction, start2, end2)
    partner_of_end1 = np.where(same_direction, end2, start2)
    rows = np.concatenate([3 * tri1 + start1, 3 * tri1 + end1])
    cols = np.concatenate([3 * tri2 + partner_of_start1, 3 * tri2 + partner_of_end1])
    corners = 3 * len(tris)
    graph = sparse.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(corners, corners))
    _, labels = _graph_components(graph, directed=False)
    fans = np.unique(tris.reshape(-1) * np.int64(corners) + labels)  # one entry per (vertex, fan)
    _, fans_per_vertex = np.unique(fans // corners, return_counts=True)
    return int(np.count_nonzero(fans_per_vertex > 1))


def edge_manifoldness(surface, triangles=None) -> EdgeReport:
    """Count boundary, non-manifold and inconsistently oriented edges and pinched vertices."""
    points, tris = surface_arrays(surface, triangles)
    if len(tris) == 0:
        return EdgeReport(0, 0, 0, 0, 0, 0)
    edges = _edges(points.shape[0], tris)
    direction = np.where(edges.forward, 1, -1)
    direction_sum = np.bincount(edges.inverse, weights=direction, minlength=edges.unique_keys.size)
    even = edges.counts % 2 == 0
    return EdgeReport(
        edges=int(edges.unique_keys.size),
        boundary_edges=int(np.count_nonzero(edges.counts == 1)),
        nonmanifold_edges=int(np.count_nonzero(edges.counts > 2)),
        inconsistent_edges=int(np.count_nonzero(even & (direction_sum != 0))),
        nonmanifold_vertices=_nonmanifold_vertices(tris, edges),
        odd_edges=int(np.count_nonzero(~even)),
    )


def is_watertight(surface, triangles=None) -> bool:
    """Closed: every edge is shared by an even number of triangles (see :attr:`EdgeReport.watertight`)."""
    return edge_manifoldness(surface, triangles).watertight


def is_manifold(surface, triangles=None) -> bool:
    """Manifold (with boundary allowed): no edge in three or more triangles, no pinched vertex."""
    return edge_manifoldness(surface, triangles).manifold


def _component_labels(points_count: int, tris: np.ndarray) -> tuple[int, np.ndarray]:
    """Number of vertex-connected triangle components and the component of each triangle."""
    if len(tris) == 0:
        return 0, np.empty(0, dtype=np.int64)
    rows = tris.reshape(-1)
    cols = tris[:, [1, 2, 0]].reshape(-1)
    graph = sparse.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)),
                              shape=(points_count, points_count))
    _, labels = _graph_components(graph, directed=False)
    _, triangle_labels = np.unique(labels[tris[:, 0]], return_inverse=True)
    return int(triangle_labels.max()) + 1, triangle_labels


def connected_components(surface, triangles=None) -> int:
    """Number of pieces of the surface (triangles sharing a vertex belong to the same piece)."""
    points, tris = surface_arrays(surface, triangles)
    return _component_labels(points.shape[0], tris)[0]


@dataclass(frozen=True)
class OrientationReport:
    """Orientation of each connected piece of a surface.

    Attributes
    ----------
    volumes : ndarray (c,)
        Signed enclosed volume of each piece (mm^3).
    closed : ndarray (c,) of bool
        Whether each piece is closed (each of its edges shared by an even number of triangles).
    depth : ndarray (c,) of int
        For closed pieces, how many other closed pieces enclose it (0 for open pieces).
    outward : bool
        Every closed piece faces away from the solid: positive volume at even depth (an outer surface or an island
        in a cavity), negative at odd depth (a cavity's wall). True when there is no closed piece.
    """

    volumes: np.ndarray
    closed: np.ndarray
    depth: np.ndarray
    outward: bool

    @property
    def components(self) -> int:
        return int(self.volumes.size)


def orientation_outward(surface, triangles=None) -> OrientationReport:
    """Check that the triangles of every closed piece face away from the solid (see :class:`OrientationReport`).

    Nesting depth comes from :func:`ray_crossings`: a point of each closed piece is tested against every
    other closed piece whose bounding box contains it.
    """
    points, tris = surface_arrays(surface, triangles)
    count, labels = _component_labels(points.shape[0], tris)
    volumes = np.bincount(labels, weights=signed_volumes(points, tris), minlength=count)
    edges = _edges(points.shape[0], tris) if len(tris) else None
    closed = np.ones(count, dtype=bool)
    if edges is not None:
        open_edge = edges.counts[edges.inverse] % 2 == 1
        closed[np.unique(np.repeat(labels, 3)[open_edge])] = False
    depth = _nesting_depth(points, tris, labels, closed)
    expected_sign = np.where(depth % 2 == 0, 1.0, -1.0)
    outward = bool(np.all(np.sign(volumes[closed]) == expected_sign[closed]))
    return OrientationReport(volumes=volumes, closed=closed, depth=depth, outward=outward)


def _nesting_depth(points, tris, labels, closed) -> np.ndarray:
    count = closed.size
    depth = np.zeros(count, dtype=np.int64)
    closed_ids = np.flatnonzero(closed)
    if closed_ids.size < 2:
        return depth
    order = np.argsort(labels, kind="stable")
    starts = np.searchsorted(labels[order], np.arange(count + 1))
    corners = points[tris[order]]  # (m, 3, 3), grouped by piece
    piece_low = np.minimum.reduceat(corners.min(axis=1), starts[:-1])
    piece_high = np.maximum.reduceat(corners.max(axis=1), starts[:-1])
    # A point inside one of the piece's triangles: pieces do not touch, so it is inside exactly the pieces that
    # enclose the whole piece.
    probes = corners[starts[closed_ids]].mean(axis=1)
    for outer in closed_ids:
        inside_box = np.all((probes > piece_low[outer]) & (probes < piece_high[outer]), axis=1)
        inside_box &= closed_ids != outer
        if not inside_box.any():
            continue
        crossings = ray_crossings(points, tris[order[starts[outer]:starts[outer + 1]]], probes[inside_box])
        depth[closed_ids[inside_box][crossings % 2 == 1]] += 1
    return depth


def ray_crossings(points: np.ndarray, triangles: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """How many triangles the ray from each origin towards +x passes through.

    For a closed surface an odd count means the origin is enclosed. Rays that meet an edge or a vertex exactly,
    which happens all the time on voxel and grid-aligned surfaces, are decided by simulation of simplicity: the
    origin is moved by ``(0, e, e^2)`` for an infinitesimal ``e``, and each edge's side test is evaluated once,
    from its lower to its higher vertex index, for every triangle that shares it. So a ray through an edge counts
    exactly one of the triangles on each side, and the count is exact for any closed surface, manifold or not.

    Parameters
    ----------
    points : ndarray (n, 3)
    triangles : ndarray (m, 3) of int
        Vertex indices; triangles that share an edge must share its two indices.
    origins : ndarray (k, 3)
        Ray origins; none may lie on the surface.

    Returns
    -------
    ndarray (k,) of int
    """
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    origins = np.atleast_2d(np.asarray(origins, dtype=np.float64))
    result = np.zeros(origins.shape[0], dtype=np.int64)
    if len(triangles) == 0 or len(origins) == 0:
        return result
    corners = points[triangles]  # (m, 3 corners, xyz)
    y_low, y_high = corners[:, :, 1].min(axis=1), corners[:, :, 1].max(axis=1)
    z_low, z_high = corners[:, :, 2].min(axis=1), corners[:, :, 2].max(axis=1)
    # Bucket the triangles on a (y, z) grid with cells as large as the largest triangle: a ray can only meet the
    # triangles whose lower corner lies in its own cell or the cells just below it in y and z.
    cell_y = max(float((y_high - y_low).max()), 1e-12)
    cell_z = max(float((z_high - z_low).max()), 1e-12)
    y0, z0 = float(y_low.min()), float(z_low.min())
    rows = int((y_low.max() - y0) // cell_y) + 2
    bucket = ((z_low - z0) // cell_z).astype(np.int64) * rows + ((y_low - y0) // cell_y).astype(np.int64)
    by_bucket = np.argsort(bucket, kind="stable")
    bucket_sorted = bucket[by_bucket]
    edge_ends = ((0, 1), (1, 2), (2, 0))
    for k, origin in enumerate(origins):
        _, y, z = origin
        row, layer = np.floor((y - y0) / cell_y), np.floor((z - z0) / cell_z)
        if row < 0 or layer < 0 or row > rows:
            continue
        window = []
        for cell in (int(layer) * rows + int(row), int(layer - 1) * rows + int(row)):
            first = np.searchsorted(bucket_sorted, cell - 1, "left")  # this row and the one below
            window.append(by_bucket[first:np.searchsorted(bucket_sorted, cell, "right")])
        window = np.concatenate(window)
        near = window[(z_low[window] <= z) & (z_high[window] >= z) & (y_low[window] <= y) & (y_high[window] >= y)]
        if near.size == 0:
            continue
        tri = triangles[near]
        sides = []
        for i, j in edge_ends:
            forward = tri[:, i] < tri[:, j]
            u = np.where(forward[:, None], corners[near, i], corners[near, j])
            v = np.where(forward[:, None], corners[near, j], corners[near, i])
            side = _perturbed_side(u, v, y, z)
            sides.append(np.where(forward, side, -side))
        inside = (sides[0] == sides[1]) & (sides[1] == sides[2])
        if not inside.any():
            continue
        a, b, c = (corners[near[inside], i] for i in range(3))
        normal = np.cross(b - a, c - a)
        usable = normal[:, 0] != 0.0
        hit_x = a[usable, 0] - (normal[usable, 1] * (y - a[usable, 1])
                                + normal[usable, 2] * (z - a[usable, 2])) / normal[usable, 0]
        result[k] = int(np.count_nonzero(hit_x > origin[0]))
    return result


def _perturbed_side(u: np.ndarray, v: np.ndarray, y: float, z: float) -> np.ndarray:
    """Side (+1 or -1) of the point (y + e, z + e^2) relative to the (y, z) projection of edges u -> v."""
    dy = v[:, 1] - u[:, 1]
    dz = v[:, 2] - u[:, 2]
    side = np.sign(dy * (z - u[:, 2]) - dz * (y - u[:, 1]))
    side = np.where(side != 0, side, np.sign(-dz))  # the e term
    return np.where(side != 0, side, np.sign(dy))  # the e^2 term; zero only for an edge seen end-on
