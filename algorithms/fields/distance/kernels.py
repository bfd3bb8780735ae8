"""numba kernels of the exact band distances (:mod:`.distance`): triangle frames, the point-triangle distance in the
triangle's own frame, and the slice-by-slice scan of per-triangle bounding polytopes.

Coordinates are the grid's own frame in mm: ``(p - origin) @ direction``, so voxel ``(i, j, k)`` sits at
``(i sx, j sy, k sz)``; the rotation keeps lengths, so distances are Euclidean mm. Arrays are ``(nz, ny, nx)``.

Triangle frame (source 002, section 3.1.3, after Sigg et al. 2003): ``v0 v1`` is the longest edge, ``o`` the foot of
the altitude from ``v2`` on it, ``r`` the unit vector from ``v0`` to ``v1``, ``s`` from ``o`` to ``v2``, ``t = r x
s`` the normal; ``a = |v1 - o|``, ``b = |v0 - o|``, ``h = |v2 - o|``. ``frames[t]`` holds ``o, r, s, t, a, b, h``
(15 floats) and ``frame_vertices[t]`` the point indices ``v0, v1, v2``.

Polytopes (the regions scanned for a triangle): kind 0, the triangle's prism (its own region, ``|t| <= d`` over the
triangle); kind 1, the source's box (``r in [-b - d, a + d]``, ``s in [-d, h + d]``, ``t in [-d, d]``), used for
every triangle in ``regions="box"`` and for degenerate triangles; kind 2, an edge's wedge; kind 3, a vertex's cone
(see :mod:`.characteristics`). Each polytope is a set of half-spaces ``n . x <= c`` (an optional ball) for the
rows, and points whose convex hull contains it for the slices and rows it meets.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

MAX_PLANES = 24
MAX_VERTICES = 24
FRAME_SIZE = 15

#: How a region's hull points are connected: the edges between them (pairs of point indices).
PRISM, CUBE, WEDGE, PYRAMID = 0, 1, 2, 3
#: Prism points: corner c at -d is 2c, at +d 2c + 1.
PRISM_EDGES = np.array([[0, 1], [2, 3], [4, 5], [0, 2], [2, 4], [4, 0], [1, 3], [3, 5], [5, 1]], dtype=np.int64)
#: Box points: index bits are the three axes, so edges join indices differing in one bit.
CUBE_EDGES = np.array([[0, 1], [0, 2], [0, 4], [1, 3], [1, 5], [2, 3], [2, 6], [3, 7], [4, 5], [4, 6], [5, 7],
                       [6, 7]], dtype=np.int64)
#: Wedge points: per end (offset 0 or 4) the edge point, the two arc ends and the far corner.
WEDGE_EDGES = np.array([[0, 1], [1, 3], [3, 2], [2, 0], [4, 5], [5, 7], [7, 6], [6, 4], [0, 4], [1, 5], [2, 6],
                        [3, 7]], dtype=np.int64)


# ----------------------------------------------------------------------------------------------------------------
# Frames and the distance in a frame
# ----------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def triangle_frames(points, triangles, frames, frame_vertices, rotation, degenerate):
    """Fill ``frames`` (m, 15), ``frame_vertices`` (m, 3), ``rotation`` (m,) and ``degenerate`` (m,).

    ``frame_vertices[t]`` is ``triangles[t]`` rotated left by ``rotation[t]``. A triangle whose height over its
    longest edge is below 1e-12 of that edge (or whose edges have no length) gets the frame of the segment
    (``h = 0``) or the point (``a = b = h = 0``), which the distance formula handles. ``degenerate`` marks the
    triangles whose height is below 1e-6 of the longest edge: their normals are too uncertain to bound regions
    with, so they are scanned with the source's box and left out of the edge and vertex neighbourhoods.
    """
    for t in range(triangles.shape[0]):
        best = -1.0
        first = 0
        for e in range(3):
            p = triangles[t, e]
            q = triangles[t, (e + 1) % 3]
            length = ((points[q, 0] - points[p, 0]) ** 2 + (points[q, 1] - points[p, 1]) ** 2
                      + (points[q, 2] - points[p, 2]) ** 2)
            if length > best:
                best = length
                first = e
        v0 = triangles[t, first]
        v1 = triangles[t, (first + 1) % 3]
        v2 = triangles[t, (first + 2) % 3]
        frame_vertices[t, 0] = v0
        frame_vertices[t, 1] = v1
        frame_vertices[t, 2] = v2
        rotation[t] = first
        length = np.sqrt(best)
        if length > 0.0:
            rx = (points[v1, 0] - points[v0, 0]) / length
            ry = (points[v1, 1] - points[v0, 1]) / length
            rz = (points[v1, 2] - points[v0, 2]) / length
        else:
            rx, ry, rz = 1.0, 0.0, 0.0
        along = ((points[v2, 0] - points[v0, 0]) * rx + (points[v2, 1] - points[v0, 1]) * ry
                 + (points[v2, 2] - points[v0, 2]) * rz)
        ox = points[v0, 0] + along * rx
        oy = points[v0, 1] + along * ry
        oz = points[v0, 2] + along * rz
        sx = points[v2, 0] - ox
        sy = points[v2, 1] - oy
        sz = points[v2, 2] - oz
        height = np.sqrt(sx * sx + sy * sy + sz * sz)
        flat = not (length > 0.0 and height > 1e-12 * length)
        if not flat:
            sx /= height
            sy /= height
            sz /= height
        else:
            height = 0.0
            if abs(rx) < 0.9:  # any unit vector perpendicular to r
                sx, sy, sz = 0.0, -rz, ry
            else:
                sx, sy, sz = rz, 0.0, -rx
            norm = np.sqrt(sx * sx + sy * sy + sz * sz)
            sx /= norm
            sy /= norm
            sz /= norm
        frames[t, 0] = ox
        frames[t, 1] = oy
        frames[t, 2] = oz
        frames[t, 3] = rx
        frames[t, 4] = ry
        frames[t, 5] = rz
        frames[t, 6] = sx
        frames[t, 7] = sy
        frames[t, 8] = sz
        frames[t, 9] = ry * sz - rz * sy
        frames[t, 10] = rz * sx - rx * sz
        frames[t, 11] = rx * sy - ry * sx
        frames[t, 12] = max(length - along, 0.0)  # a
        frames[t, 13] = max(along, 0.0)  # b
        frames[t, 14] = height  # h
        degenerate[t] = flat or height <= 1e-6 * length


@njit(cache=True, nogil=True)
def frame_distance2(r, s, t, a, b, h):
    """Squared distance of the point ``(r, s, t)`` (triangle frame) to the triangle ``a, b, h``: source 002's
    figure 3.3 (after Sigg et al.), regions I-VI; mirrored at the s axis for ``r < 0``."""
    if r < 0.0:
        r = -r
        a = b
    if s < 0.0:  # regions II, III: below the longest edge
        r = max(r - a, 0.0)
        return r * r + s * s + t * t
    length2 = a * a + h * h
    if length2 == 0.0:
        return r * r + s * s + t * t
    rp = (a * r - h * s + h * h) / length2
    sp = (h * r + a * s - a * h) / length2
    rp = max(-rp, rp - 1.0, 0.0)  # IV, V, VI
    sp = max(sp, 0.0)  # I, V
    return (rp * rp + sp * sp) * length2 + t * t


@njit(cache=True, nogil=True)
def frame_feature(r, s, a, b, h):
    """Which part of the triangle is nearest to ``(r, s, .)``: 0 inside, 1 edge v0-v1, 2 edge v1-v2, 3 edge v2-v0,
    4 vertex v0, 5 vertex v1, 6 vertex v2 (the same case split as :func:`frame_distance2`)."""
    left = r < 0.0
    if left:
        r = -r
        a = b
    if s < 0.0:
        if r <= a:
            return 1
        return 4 if left else 5
    length2 = a * a + h * h
    if length2 == 0.0:
        return 4 if left else 5
    rp = (a * r - h * s + h * h) / length2
    sp = (h * r + a * s - a * h) / length2
    if sp <= 0.0:
        return 0
    if rp < 0.0:
        return 6
    if rp > 1.0:
        return 4 if left else 5
    return 3 if left else 2


@njit(cache=True, nogil=True)
def point_triangle_distance2(frames, t, x, y, z):
    """Squared distance (mm^2) of the point ``(x, y, z)`` to triangle ``t``."""
    dx = x - frames[t, 0]
    dy = y - frames[t, 1]
    dz = z - frames[t, 2]
    r = dx * frames[t, 3] + dy * frames[t, 4] + dz * frames[t, 5]
    s = dx * frames[t, 6] + dy * frames[t, 7] + dz * frames[t, 8]
    n = dx * frames[t, 9] + dy * frames[t, 10] + dz * frames[t, 11]
    return frame_distance2(r, s, n, frames[t, 12], frames[t, 13], frames[t, 14])


@njit(cache=True, nogil=True, parallel=True)
def distances_to_mesh(frames, samples, out2, nearest):
    """Brute force: squared distance of each sample ``(q, 3)`` to every triangle (the reference of the tests)."""
    for q in prange(samples.shape[0]):
        best = np.inf
        which = -1
        for t in range(frames.shape[0]):
            d2 = point_triangle_distance2(frames, t, samples[q, 0], samples[q, 1], samples[q, 2])
            if d2 < best:
                best = d2
                which = t
        out2[q] = best
        nearest[q] = which


# ----------------------------------------------------------------------------------------------------------------
# Polytopes
# ----------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _plane(planes, n, nx, ny, nz, c):
    planes[n, 0] = nx
    planes[n, 1] = ny
    planes[n, 2] = nz
    planes[n, 3] = c
    return n + 1


@njit(cache=True, nogil=True)
def _vertex(vertices, n, x, y, z):
    vertices[n, 0] = x
    vertices[n, 1] = y
    vertices[n, 2] = z
    return n + 1


@njit(cache=True, nogil=True)
def _frame_plane(planes, n, frames, t, axis, sign, limit):
    """The half-space ``sign * (axis of frame t) . (x - o) <= limit``."""
    ax = sign * frames[t, 3 * axis + 3]
    ay = sign * frames[t, 3 * axis + 4]
    az = sign * frames[t, 3 * axis + 5]
    return _plane(planes, n, ax, ay, az, limit + ax * frames[t, 0] + ay * frames[t, 1] + az * frames[t, 2])


@njit(cache=True, nogil=True)
def build_polytope(pid, n_triangles, tri_kind, frames, frame_vertices, points, wedges, wedge_vertices,
                   cone_info, cone_start, cone_rays, cone_edges, reach, slack, planes, vertices, sphere):
    """Write polytope ``pid``'s half-spaces and hull points; returns ``(owner triangle, planes, points, shape)``.

    ``reach`` is the band width d plus the slack; ``sphere[3] < 0`` when there is no ball constraint. ``shape`` tells
    how the hull points are connected (:data:`PRISM`, :data:`CUBE`, :data:`WEDGE` or :data:`PYRAMID`).
    """
    sphere[3] = -1.0
    # Counters and axes passed to the helpers are int64 values, never literal constants: numba would compile a
    # helper once for each literal argument.
    np_ = np.int64(0)
    nv = np.int64(0)
    if pid < n_triangles:
        t = pid
        a = frames[t, 12]
        b = frames[t, 13]
        h = frames[t, 14]
        if tri_kind[t] == 1:  # the source's box, grown by d: r <= a + d, -r <= b + d, s <= h + d, -s <= d, |t| <= d
            for axis in range(3):
                np_ = _frame_plane(planes, np_, frames, t, axis, 1.0, (a if axis == 0 else (h if axis == 1 else 0.0))
                                   + reach)
                np_ = _frame_plane(planes, np_, frames, t, axis, -1.0, (b if axis == 0 else 0.0) + reach)
            for ir in range(2):
                rr = a + reach if ir == 0 else -b - reach
                for js in range(2):
                    ss = h + reach if js == 0 else -reach
                    for kt in range(2):
                        tt = reach if kt == 0 else -reach
                        nv = _vertex(vertices, nv,
                                     frames[t, 0] + rr * frames[t, 3] + ss * frames[t, 6] + tt * frames[t, 9],
                                     frames[t, 1] + rr * frames[t, 4] + ss * frames[t, 7] + tt * frames[t, 10],
                                     frames[t, 2] + rr * frames[t, 5] + ss * frames[t, 8] + tt * frames[t, 11])
            return t, np_, nv, CUBE
        # the prism over the triangle: s >= 0, both slanted sides, |t| <= d
        np_ = _frame_plane(planes, np_, frames, t, np.int64(1), -1.0, slack)
        right = np.sqrt(a * a + h * h)
        left = np.sqrt(b * b + h * h)
        # right side through v1 (r = a, s = 0) with outward normal (h, a) / right in (r, s)
        cr = h / right
        cs = a / right
        nx = cr * frames[t, 3] + cs * frames[t, 6]
        ny = cr * frames[t, 4] + cs * frames[t, 7]
        nz = cr * frames[t, 5] + cs * frames[t, 8]
        np_ = _plane(planes, np_, nx, ny, nz, slack + cr * a + nx * frames[t, 0] + ny * frames[t, 1]
                     + nz * frames[t, 2])
        # left side through v0 (r = -b, s = 0) with outward normal (-h, b) / left
        cr = -h / left
        cs = b / left
        nx = cr * frames[t, 3] + cs * frames[t, 6]
        ny = cr * frames[t, 4] + cs * frames[t, 7]
        nz = cr * frames[t, 5] + cs * frames[t, 8]
        np_ = _plane(planes, np_, nx, ny, nz, slack - cr * b + nx * frames[t, 0] + ny * frames[t, 1]
                     + nz * frames[t, 2])
        for sign in (1.0, -1.0):
            np_ = _frame_plane(planes, np_, frames, t, np.int64(2), sign, reach)
        for corner in range(3):
            v = frame_vertices[t, corner]
            for sign in (-1.0, 1.0):
                nv = _vertex(vertices, nv, points[v, 0] + sign * reach * frames[t, 9],
                             points[v, 1] + sign * reach * frames[t, 10], points[v, 2] + sign * reach * frames[t, 11])
        return t, np_, nv, PRISM
    pid -= n_triangles
    if pid < wedges.shape[0]:
        # wedges[w] = edge direction e (3), arc ends u1 (3), u2 (3), mid um (3), 1 / cos(half width)
        p0 = wedge_vertices[pid, 0]
        p1 = wedge_vertices[pid, 1]
        ex, ey, ez = wedges[pid, 0], wedges[pid, 1], wedges[pid, 2]
        np_ = _plane(planes, np_, -ex, -ey, -ez, slack - ex * points[p0, 0] - ey * points[p0, 1] - ez * points[p0, 2])
        np_ = _plane(planes, np_, ex, ey, ez, slack + ex * points[p1, 0] + ey * points[p1, 1] + ez * points[p1, 2])
        for side in range(2):
            ux, uy, uz = wedges[pid, 3 + 3 * side], wedges[pid, 4 + 3 * side], wedges[pid, 5 + 3 * side]
            mx = ey * uz - ez * uy
            my = ez * ux - ex * uz
            mz = ex * uy - ey * ux
            if mx * wedges[pid, 9] + my * wedges[pid, 10] + mz * wedges[pid, 11] > 0.0:
                mx, my, mz = -mx, -my, -mz
            np_ = _plane(planes, np_, mx, my, mz, slack + mx * points[p0, 0] + my * points[p0, 1] + mz * points[p0, 2])
        mx, my, mz = wedges[pid, 9], wedges[pid, 10], wedges[pid, 11]
        np_ = _plane(planes, np_, mx, my, mz, reach + mx * points[p0, 0] + my * points[p0, 1] + mz * points[p0, 2])
        far = reach * wedges[pid, 12]
        for end in range(2):
            p = p0 if end == 0 else p1
            nv = _vertex(vertices, nv, points[p, 0], points[p, 1], points[p, 2])
            for side in range(2):
                nv = _vertex(vertices, nv, points[p, 0] + reach * wedges[pid, 3 + 3 * side],
                             points[p, 1] + reach * wedges[pid, 4 + 3 * side],
                             points[p, 2] + reach * wedges[pid, 5 + 3 * side])
            nv = _vertex(vertices, nv, points[p, 0] + far * mx, points[p, 1] + far * my, points[p, 2] + far * mz)
        return wedge_vertices[pid, 2], np_, nv, WEDGE
    pid -= wedges.shape[0]
    # cone_info[c] = vertex, owner, fallback (ball), ; the centre direction follows in cone_rays' first row
    v = cone_info[pid, 0]
    vx, vy, vz = points[v, 0], points[v, 1], points[v, 2]
    for e in range(cone_start[pid, 1], cone_start[pid + 1, 1]):
        if np_ >= MAX_PLANES - 1:
            break  # dropping a half-space only enlarges the region
        ax, ay, az = cone_edges[e, 0], cone_edges[e, 1], cone_edges[e, 2]
        np_ = _plane(planes, np_, ax, ay, az, slack + ax * vx + ay * vy + az * vz)
    first = cone_start[pid, 0]
    if cone_info[pid, 2] == 0:
        cx, cy, cz = cone_rays[first, 0], cone_rays[first, 1], cone_rays[first, 2]
        np_ = _plane(planes, np_, cx, cy, cz, reach + cx * vx + cy * vy + cz * vz)
        nv = _vertex(vertices, nv, vx, vy, vz)
        for q in range(first + 1, cone_start[pid + 1, 0]):
            scale = reach / (cone_rays[q, 0] * cx + cone_rays[q, 1] * cy + cone_rays[q, 2] * cz)
            nv = _vertex(vertices, nv, vx + scale * cone_rays[q, 0], vy + scale * cone_rays[q, 1],
                         vz + scale * cone_rays[q, 2])
        return cone_info[pid, 1], np_, nv, PYRAMID
    sphere[0], sphere[1], sphere[2], sphere[3] = vx, vy, vz, reach * reach
    for ix in (-1.0, 1.0):
        for iy in (-1.0, 1.0):
            for iz in (-1.0, 1.0):
                nv = _vertex(vertices, nv, vx + ix * reach, vy + iy * reach, vz + iz * reach)
    return cone_info[pid, 1], np_, nv, CUBE


@njit(cache=True, nogil=True)
def _slice_range(pid, n_triangles, tri_kind, frames, frame_vertices, points, wedges, wedge_vertices, cone_info,
                 cone_start, cone_rays, cone_edges, reach, slack, sz, nz, first, last, planes, vertices, sphere):
    _, _, nv, _ = build_polytope(pid, n_triangles, tri_kind, frames, frame_vertices, points, wedges, wedge_vertices,
                              cone_info, cone_start, cone_rays, cone_edges, reach, slack, planes, vertices, sphere)
    low = np.inf
    high = -np.inf
    for q in range(nv):
        low = min(low, vertices[q, 2])
        high = max(high, vertices[q, 2])
    first[pid] = max(int(np.ceil((low - slack) / sz)), 0)
    last[pid] = min(int(np.floor((high + slack) / sz)), nz - 1)


@njit(cache=True, nogil=True, parallel=True)
def polytope_slices(n_polytopes, n_triangles, tri_kind, frames, frame_vertices, points, wedges, wedge_vertices,
                    cone_info, cone_start, cone_rays, cone_edges, reach, slack, sz, nz, first, last):
    """The first and last slice each polytope's hull meets (``last < first`` when none)."""
    chunk = 4096
    for c in prange((n_polytopes + chunk - 1) // chunk):
        planes = np.empty((MAX_PLANES, 4))
        vertices = np.empty((MAX_VERTICES, 3))
        sphere = np.empty(4)
        for pid in range(c * chunk, min((c + 1) * chunk, n_polytopes)):
            _slice_range(pid, n_triangles, tri_kind, frames, frame_vertices, points, wedges, wedge_vertices,
                         cone_info, cone_start, cone_rays, cone_edges, reach, slack, sz, nz, first, last, planes,
                         vertices, sphere)
