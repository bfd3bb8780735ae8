"""The regions each triangle is scanned over, tighter than the source's boxes: the characteristic polytopes of the
mesh's faces, edges and vertices (Mauch's characteristics/scan-conversion method, which source 002 describes in
section 3.1.3 and points to in 3.3 as the way to faster scans: "besser zugeschnittene Polyeder").

If ``q`` is the point of the mesh nearest to ``p``, the unit direction ``u = (p - q) / |p - q|`` makes no acute
angle with any direction leaving ``q`` within the mesh (else moving ``q`` that way would come closer). So

- ``q`` inside a face: ``u`` is the face's normal (either side): ``p`` lies in the face's **prism**;
- ``q`` on an edge: ``u`` is perpendicular to the edge and ``u . w <= 0`` for the in-plane direction ``w`` into each
  face at the edge: an arc of directions (empty, or up to a half circle at a boundary edge) - the edge's **wedge**;
- ``q`` at a vertex: ``u . e <= 0`` for every edge direction ``e`` leaving the vertex - the vertex's polar **cone**.

No orientation or closedness is assumed: boundary and non-manifold edges and vertices get their (larger or
smaller) arcs and cones from the same rule, and faces that meet ``q`` without sharing its indices only make the
true region smaller. Wedges and cones with no interior are skipped: their points are limits of points of the
other regions, which are closed. Each wedge and cone is scanned with the distance to one triangle that contains its
edge or vertex (its owner), whose distance there is the distance to the edge or vertex.

Arrays: ``points`` (n, 3) in the grid frame (mm), ``triangles`` (m, 3). Edge ``e`` joins ``edges[e]`` (lower index
first); ``edge_faces[edge_start[e]:edge_start[e + 1]]`` are its triangles; likewise ``vertex_faces``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Largest number of distinct edge directions at a vertex whose cone is worked out exactly (else: a ball).
MAX_VERTEX_EDGES = 48
#: Most rays a cone may have before it is bounded by a ball instead (the kernels keep at most 24 hull points).
MAX_CONE_RAYS = 23
#: Cones whose rays make less than this cosine with their centre direction are bounded by a ball.
MIN_CONE_COSINE = 0.1


def mesh_topology(triangles: np.ndarray, n_points: int):
    """Edges and incidences: ``edges`` (E, 2), ``edge_start``/``edge_faces``, ``vertex_start``/``vertex_faces`` and
    ``triangle_edges`` (m, 3): the edge ids of ``(c0, c1), (c1, c2), (c2, c0)`` of each triangle."""
    m = len(triangles)
    half = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]).astype(np.int64)
    low = half.min(axis=1)
    high = half.max(axis=1)
    key = low * np.int64(n_points) + high
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    new = np.empty(len(order), dtype=bool)
    new[:1] = True
    new[1:] = sorted_key[1:] != sorted_key[:-1]
    edge_of_sorted = np.cumsum(new) - 1
    n_edges = int(edge_of_sorted[-1]) + 1 if len(order) else 0
    edge_of_half = np.empty(len(order), dtype=np.int64)
    edge_of_half[order] = edge_of_sorted
    firsts = order[new]
    edges = np.stack([low[firsts], high[firsts]], axis=1)
    edge_start = np.zeros(n_edges + 1, dtype=np.int64)
    np.cumsum(np.bincount(edge_of_sorted, minlength=n_edges), out=edge_start[1:])
    edge_faces = (order % max(m, 1)).astype(np.int32)
    triangle_edges = edge_of_half.reshape(3, m).T.copy()
    corner_vertex = triangles.astype(np.int64).ravel()
    vorder = np.argsort(corner_vertex, kind="stable")
    vertex_start = np.zeros(n_points + 1, dtype=np.int64)
    np.cumsum(np.bincount(corner_vertex, minlength=n_points), out=vertex_start[1:])
    vertex_faces = (vorder // 3).astype(np.int32)
    return edges, edge_start, edge_faces, vertex_start, vertex_faces, triangle_edges


@njit(cache=True, nogil=True)
def _third(triangles, f, p0, p1):
    for c in range(3):
        v = triangles[f, c]
        if v != p0 and v != p1:
            return v
    return -1


@njit(cache=True, nogil=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, nogil=True)
def edge_wedges(points, triangles, degenerate, edges, edge_start, edge_faces, reach, slack):
    """The wedge pieces of every edge (each at most a quarter turn): ``wedges`` (w, 13) = edge direction, arc ends
    ``u1``, ``u2``, mid direction, ``1 / cos(half width)``; ``wedge_vertices`` (w, 3) = the edge's points and the
    owner triangle. Edges without a non-degenerate triangle, and arcs narrower than the slack at the band's far end,
    have none."""
    n_edges = edges.shape[0]
    out = np.empty((2 * n_edges, 13))
    ends = np.empty((2 * n_edges, 3), dtype=np.int64)
    count = 0
    e_ = np.empty(3)
    w = np.empty(3)
    x_axis = np.empty(3)
    y_axis = np.empty(3)
    for e in range(n_edges):
        p0 = edges[e, 0]
        p1 = edges[e, 1]
        for c in range(3):
            e_[c] = points[p1, c] - points[p0, c]
        length = np.sqrt(_dot(e_, e_))
        if length == 0.0:
            continue
        for c in range(3):
            e_[c] /= length
        owner = -1
        low = -0.5 * np.pi
        high = 0.5 * np.pi
        for q in range(edge_start[e], edge_start[e + 1]):
            f = edge_faces[q]
            if degenerate[f]:
                continue
            third = _third(triangles, f, p0, p1)
            if third < 0:
                continue
            for c in range(3):
                w[c] = points[third, c] - points[p0, c]
            along = _dot(w, e_)
            for c in range(3):
                w[c] -= along * e_[c]
            norm = np.sqrt(_dot(w, w))
            if norm == 0.0:
                continue
            for c in range(3):
                w[c] /= norm
            if owner < 0:
                owner = f
                for c in range(3):
                    x_axis[c] = -w[c]
                y_axis[0] = e_[1] * x_axis[2] - e_[2] * x_axis[1]
                y_axis[1] = e_[2] * x_axis[0] - e_[0] * x_axis[2]
                y_axis[2] = e_[0] * x_axis[1] - e_[1] * x_axis[0]
                continue
            angle = np.arctan2(-_dot(w, y_axis), -_dot(w, x_axis))
            low = max(low, angle - 0.5 * np.pi)
            high = min(high, angle + 0.5 * np.pi)
        if owner < 0:
            continue
        width = high - low
        if width <= 0.0 or reach * np.sin(min(width, 0.5 * np.pi)) <= slack:
            continue
        pieces = int(np.ceil(width / (0.5 * np.pi) - 1e-12))
        step = width / pieces
        for piece in range(pieces):
            a1 = low + piece * step
            a2 = a1 + step
            am = 0.5 * (a1 + a2)
            for c in range(3):
                out[count, c] = e_[c]
                out[count, 3 + c] = np.cos(a1) * x_axis[c] + np.sin(a1) * y_axis[c]
                out[count, 6 + c] = np.cos(a2) * x_axis[c] + np.sin(a2) * y_axis[c]
                out[count, 9 + c] = np.cos(am) * x_axis[c] + np.sin(am) * y_axis[c]
            out[count, 12] = 1.0 / np.cos(0.5 * step)
            ends[count, 0] = p0
            ends[count, 1] = p1
            ends[count, 2] = owner
            count += 1
    return out[:count].copy(), ends[:count].copy()


@njit(cache=True, nogil=True)
def _vertex_directions(points, triangles, degenerate, v, vertex_start, vertex_faces, directions, neighbours):
    """The distinct unit edge directions leaving ``v`` over its non-degenerate triangles; returns (count, owner,
    truncated)."""
    count = 0
    owner = -1
    truncated = False
    for q in range(vertex_start[v], vertex_start[v + 1]):
        f = vertex_faces[q]
        if degenerate[f]:
            continue
        if owner < 0:
            owner = f
        for c in range(3):
            u = triangles[f, c]
            if u == v:
                continue
            seen = False
            for n in range(count):
                if neighbours[n] == u:
                    seen = True
                    break
            if seen:
                continue
            if count == directions.shape[0]:
                truncated = True
                continue
            dx = points[u, 0] - points[v, 0]
            dy = points[u, 1] - points[v, 1]
            dz = points[u, 2] - points[v, 2]
            norm = np.sqrt(dx * dx + dy * dy + dz * dz)
            if norm == 0.0:
                continue
            directions[count, 0] = dx / norm
            directions[count, 1] = dy / norm
            directions[count, 2] = dz / norm
            neighbours[count] = u
            count += 1
    return count, owner, truncated


@njit(cache=True, nogil=True)
def _cross_into(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, nogil=True)
def _cone(directions, count, rays):
    """The polar cone of ``directions[:count]``: returns (status, number of rays) with rays[0] the centre direction
    and rays[1:] the extreme rays. Status 0: a pointed cone with interior; 1: no interior (skip); 2: contains a
    line or too wide (bound it by a ball)."""
    c = np.empty(3)
    best = 0.0
    pa = 0
    pb = 0
    for a in range(count):
        for b in range(a + 1, count):
            _cross_into(directions[a], directions[b], c)
            size = _dot(c, c)
            if size > best:
                best, pa, pb = size, a, b
    if best < 1e-18:
        return 2, 0
    normal = np.empty(3)
    _cross_into(directions[pa], directions[pb], normal)
    volume = 0.0
    for k in range(count):
        volume = max(volume, abs(_dot(normal, directions[k])))
    if volume < 1e-9:
        # all directions in one plane: the cone is the normal line (no interior) when they surround the vertex in
        # that plane (every angular gap below a half turn), else a wedge or half-space around it
        size = np.sqrt(best)
        for k in range(3):
            normal[k] /= size
        x_axis = directions[pa]
        y_axis = np.empty(3)
        _cross_into(normal, x_axis, y_axis)
        angles = np.empty(count)
        for k in range(count):
            angles[k] = np.arctan2(_dot(directions[k], y_axis), _dot(directions[k], x_axis))
        angles.sort()
        gap = angles[0] + 2.0 * np.pi - angles[count - 1]
        for k in range(1, count):
            gap = max(gap, angles[k] - angles[k - 1])
        return (1 if gap < np.pi - 1e-9 else 2), 0
    n_rays = 0
    for a in range(count):
        for b in range(a + 1, count):
            _cross_into(directions[a], directions[b], c)
            size = np.sqrt(_dot(c, c))
            if size < 1e-12:
                continue
            for sign in (1.0, -1.0):
                ux = sign * c[0] / size
                uy = sign * c[1] / size
                uz = sign * c[2] / size
                inside = True
                for k in range(count):
                    if ux * directions[k, 0] + uy * directions[k, 1] + uz * directions[k, 2] > 1e-9:
                        inside = False
                        break
                if not inside:
                    continue
                duplicate = False
                for r in range(1, n_rays + 1):
                    if ux * rays[r, 0] + uy * rays[r, 1] + uz * rays[r, 2] > 1.0 - 1e-12:
                        duplicate = True
                        break
                if duplicate:
                    continue
                if n_rays + 1 >= rays.shape[0]:
                    return 2, 0
                n_rays += 1
                rays[n_rays, 0] = ux
                rays[n_rays, 1] = uy
                rays[n_rays, 2] = uz
    if n_rays < 3:
        return 1, 0  # the cone is {0}, a ray or a flat sector: no interior
    spread = 0.0
    for a in range(1, n_rays + 1):
        for b in range(a + 1, n_rays + 1):
            _cross_into(rays[a], rays[b], c)
            for k in range(1, n_rays + 1):
                spread = max(spread, abs(_dot(c, rays[k])))
    if spread < 1e-9:
        return 1, 0
    cx = 0.0
    cy = 0.0
    cz = 0.0
    for r in range(1, n_rays + 1):
        cx += rays[r, 0]
        cy += rays[r, 1]
        cz += rays[r, 2]
    norm = np.sqrt(cx * cx + cy * cy + cz * cz)
    if norm < 1e-12:
        return 2, 0
    cx /= norm
    cy /= norm
    cz /= norm
    for r in range(1, n_rays + 1):
        if cx * rays[r, 0] + cy * rays[r, 1] + cz * rays[r, 2] < MIN_CONE_COSINE:
            return 2, 0
    rays[0, 0] = cx
    rays[0, 1] = cy
    rays[0, 2] = cz
    return 0, n_rays


@njit(cache=True, nogil=True)
def _cone_count(points, triangles, degenerate, vertex_start, vertex_faces, status, n_rays, n_edges, owners, v,
                directions, neighbours, rays):
    count, owner, truncated = _vertex_directions(points, triangles, degenerate, v, vertex_start, vertex_faces,
                                                 directions, neighbours)
    owners[v] = owner
    status[v] = 1
    n_rays[v] = 0
    n_edges[v] = min(count, 23)
    if owner < 0 or count == 0:
        return
    if truncated:
        status[v] = 2
        return
    state, found = _cone(directions, count, rays)
    status[v] = state
    n_rays[v] = found


@njit(cache=True, nogil=True, parallel=True)
def _cone_counts(points, triangles, degenerate, vertex_start, vertex_faces, status, n_rays, n_edges, owners):
    n = vertex_start.shape[0] - 1
    chunk = 1024
    for part in prange((n + chunk - 1) // chunk):
        directions = np.empty((MAX_VERTEX_EDGES, 3))
        neighbours = np.empty(MAX_VERTEX_EDGES, dtype=np.int64)
        rays = np.empty((MAX_CONE_RAYS + 1, 3))
        for v in range(part * chunk, min((part + 1) * chunk, n)):
            _cone_count(points, triangles, degenerate, vertex_start, vertex_faces, status, n_rays, n_edges, owners,
                        v, directions, neighbours, rays)


@njit(cache=True, nogil=True)
def _cone_fill_one(points, triangles, degenerate, vertex_start, vertex_faces, kept, start, cone_info, cone_rays,
                   cone_edges, status, owners, c, directions, neighbours, rays):
    v = kept[c]
    count, _, _ = _vertex_directions(points, triangles, degenerate, v, vertex_start, vertex_faces, directions,
                                     neighbours)
    cone_info[c, 0] = v
    cone_info[c, 1] = owners[v]
    cone_info[c, 2] = 0 if status[v] == 0 else 1
    e0 = start[c, 1]
    for q in range(start[c + 1, 1] - e0):
        for k in range(3):
            cone_edges[e0 + q, k] = directions[q, k]
    r0 = start[c, 0]
    if status[v] == 0:
        _cone(directions, count, rays)
        for q in range(start[c + 1, 0] - r0):
            for k in range(3):
                cone_rays[r0 + q, k] = rays[q, k]
    else:
        for k in range(3):
            cone_rays[r0, k] = 0.0


@njit(cache=True, nogil=True, parallel=True)
def _cone_fill(points, triangles, degenerate, vertex_start, vertex_faces, kept, start, cone_info, cone_rays,
               cone_edges, status, owners):
    n = kept.shape[0]
    chunk = 1024
    for part in prange((n + chunk - 1) // chunk):
        directions = np.empty((MAX_VERTEX_EDGES, 3))
        neighbours = np.empty(MAX_VERTEX_EDGES, dtype=np.int64)
        rays = np.empty((MAX_CONE_RAYS + 1, 3))
        for c in range(part * chunk, min((part + 1) * chunk, n)):
            _cone_fill_one(points, triangles, degenerate, vertex_start, vertex_faces, kept, start, cone_info,
                           cone_rays, cone_edges, status, owners, c, directions, neighbours, rays)


def vertex_cones(points, triangles, degenerate, vertex_start, vertex_faces):
    """The cones of the vertices whose cone has an interior: ``cone_info`` (c, 3) = vertex, owner triangle, 1 when
    bounded by a ball; ``cone_start`` (c + 1, 2) = offsets into ``cone_rays`` (centre direction, then the extreme
    rays) and ``cone_edges`` (the edge directions ``e`` of the half-spaces ``u . e <= 0``)."""
    n_points = len(vertex_start) - 1
    status = np.empty(n_points, dtype=np.int64)
    n_rays = np.empty(n_points, dtype=np.int64)
    n_edges = np.empty(n_points, dtype=np.int64)
    owners = np.empty(n_points, dtype=np.int64)
    _cone_counts(points, triangles, degenerate, vertex_start, vertex_faces, status, n_rays, n_edges, owners)
    kept = np.flatnonzero(status != 1)
    rows = np.where(status[kept] == 0, n_rays[kept] + 1, 1)
    start = np.zeros((len(kept) + 1, 2), dtype=np.int64)
    np.cumsum(rows, out=start[1:, 0])
    np.cumsum(n_edges[kept], out=start[1:, 1])
    cone_info = np.empty((len(kept), 3), dtype=np.int64)
    cone_rays = np.empty((int(start[-1, 0]), 3))
    cone_edges = np.empty((int(start[-1, 1]), 3))
    _cone_fill(points, triangles, degenerate, vertex_start, vertex_faces, kept, start, cone_info, cone_rays,
               cone_edges, status, owners)
    return cone_info, start, cone_rays, cone_edges
