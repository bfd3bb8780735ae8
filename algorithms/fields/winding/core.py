"""Generalised winding numbers of triangle meshes, open or closed, with a hierarchical far-field approximation.

The winding number of a closed, outward-oriented surface at a point is the number of times the surface wraps
around it: 1 inside, 0 outside, 2 where two solids overlap. Jacobson et al. (2013) generalise it to any triangle
soup as the sum of the triangles' signed solid angles over ``4 pi``; it is harmonic, jumps by one across the
surface, and varies smoothly across holes, so ``w >= 1/2`` gives the solid a user expects of a mesh with holes or
self-intersections. Barill et al. (2018) evaluate it fast: triangles are grouped in a tree, and a group far from
the query point (farther than ``beta`` times its radius) is replaced by the Taylor expansion of its dipole
moments about its centre.

- :func:`solid_angle_winding`: the exact sum over all triangles (Van Oosterom & Strackee's solid angle), for tests
  and small meshes.
- :class:`WindingTree` / :func:`winding_numbers`: the fast evaluation (a balanced tree over the triangles in
  Morton order, expansion terms of order 0 and 1, exact leaves).
- :func:`boundary_caps`: a fan of triangles over every boundary loop, so that mesh plus caps is closed as a chain
  (every edge used as often in one direction as in the other). :mod:`.voxelise` uses it to get the integer part of
  the winding number from signed row crossings and needs the tree only near the caps (see there).

Coordinates are ``(x, y, z)`` in mm (any Cartesian frame: solid angles need true lengths, so never evaluate in an
anisotropic index frame). Triangles face along ``(p1 - p0) x (p2 - p0)``.

References
----------
A. Jacobson, L. Kavan, O. Sorkine-Hornung, "Robust inside-outside segmentation using generalized winding numbers",
ACM Transactions on Graphics 32(4), 2013. doi:10.1145/2461912.2461916.
G. Barill, N. G. Dickson, R. Schmidt, D. I. W. Levin, A. Jacobson, "Fast winding numbers for soups and clouds",
ACM Transactions on Graphics 37(4), 2018. doi:10.1145/3197517.3201337.
A. Van Oosterom, J. Strackee, "The solid angle of a plane triangle", IEEE Transactions on Biomedical Engineering
30(2), 125-126, 1983. doi:10.1109/TBME.1983.325207.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from ...common.progress import ProgressCallback, report

__all__ = ["BoundaryCaps", "WindingTree", "boundary_caps", "solid_angle_winding", "winding_numbers"]

#: Triangles per leaf of the tree.
LEAF_SIZE = 8
#: Default far-field criterion: expand a node when the query is farther than ``beta`` times its radius.
DEFAULT_BETA = 2.0


def _as_mesh(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    points = np.ascontiguousarray(points, dtype=np.float64)
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be an (n, 3) array, got shape {points.shape}")
    if triangles.size == 0:
        triangles = triangles.reshape(0, 3)
    if triangles.ndim != 2 or triangles.shape[1] != 3:
        raise ValueError(f"triangles must be an (m, 3) array of point indices, got shape {triangles.shape}")
    if triangles.size and (triangles.min() < 0 or triangles.max() >= len(points)):
        raise ValueError(f"triangle corners must be point indices in [0, {len(points)})")
    return points, triangles


# ----------------------------------------------------------------------------------------------------------------
# Exact solid angles
# ----------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, inline="always")
def _solid_angle(points, a, b, c, qx, qy, qz):
    """Signed solid angle of triangle ``(a, b, c)`` seen from ``q`` (Van Oosterom & Strackee)."""
    ax, ay, az = points[a, 0] - qx, points[a, 1] - qy, points[a, 2] - qz
    bx, by, bz = points[b, 0] - qx, points[b, 1] - qy, points[b, 2] - qz
    cx, cy, cz = points[c, 0] - qx, points[c, 1] - qy, points[c, 2] - qz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    numerator = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    denominator = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la
                   + (cx * ax + cy * ay + cz * az) * lb)
    return 2.0 * math.atan2(numerator, denominator)


@njit(cache=True, nogil=True, parallel=True)
def _exact_winding(points, triangles, queries, out):
    for q in prange(queries.shape[0]):
        total = 0.0
        for t in range(triangles.shape[0]):
            total += _solid_angle(points, triangles[t, 0], triangles[t, 1], triangles[t, 2],
                                  queries[q, 0], queries[q, 1], queries[q, 2])
        out[q] = total / (4.0 * math.pi)


def solid_angle_winding(points, triangles, queries) -> np.ndarray:
    """Exact generalised winding numbers ``(k,)`` at ``queries`` ``(k, 3)``: the sum of every triangle's signed solid
    angle over ``4 pi`` (cost: queries x triangles)."""
    points, triangles = _as_mesh(points, triangles)
    queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float64)
    out = np.empty(len(queries), dtype=np.float64)
    if len(queries) and len(triangles):
        _exact_winding(points, triangles, queries, out)
    else:
        out[:] = 0.0
    return out


# ----------------------------------------------------------------------------------------------------------------
# The tree
# ----------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _build_nodes(count, leaf_size):
    """Balanced binary tree over ``count`` items in their given order: ``(first, last, left, right)`` per node
    (``left = -1`` for leaves), root 0, children after their parent."""
    capacity = max(1, 2 * count - 1)  # a binary tree with non-empty leaves
    first = np.empty(capacity, dtype=np.int64)
    last = np.empty(capacity, dtype=np.int64)
    left = np.full(capacity, -1, dtype=np.int64)
    right = np.full(capacity, -1, dtype=np.int64)
    first[0], last[0] = 0, count
    nodes = 1
    stack = np.empty(128, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        size = last[node] - first[node]
        if size <= leaf_size:
            continue
        middle = first[node] + size // 2
        for child, lo, hi in ((nodes, first[node], middle), (nodes + 1, middle, last[node])):
            first[child], last[child] = lo, hi
            stack[top] = child
            top += 1
        left[node], right[node] = nodes, nodes + 1
        nodes += 2
    return first[:nodes], last[:nodes], left[:nodes], right[:nodes]


@njit(cache=True, nogil=True, parallel=True)
def _node_moments(points, triangles, order, first, last, centre, radius, area, dipole, moment):
    """Per node: area-weighted centre, radius (farthest corner from the centre), area, dipole ``sum A n`` and first
    moment ``sum A n (c_t - centre)^T`` (3 x 3, row = normal component)."""
    for node in prange(first.shape[0]):
        area_sum = 0.0
        cx = cy = cz = 0.0
        dx = dy = dz = 0.0
        for m in range(first[node], last[node]):
            t = order[m]
            a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
            vx, vy, vz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
            nx, ny, nz = 0.5 * (uy * vz - uz * vy), 0.5 * (uz * vx - ux * vz), 0.5 * (ux * vy - uy * vx)
            weight = math.sqrt(nx * nx + ny * ny + nz * nz)
            area_sum += weight
            cx += weight * (points[a, 0] + points[b, 0] + points[c, 0]) / 3.0
            cy += weight * (points[a, 1] + points[b, 1] + points[c, 1]) / 3.0
            cz += weight * (points[a, 2] + points[b, 2] + points[c, 2]) / 3.0
            dx += nx
            dy += ny
            dz += nz
        if area_sum > 0.0:
            cx, cy, cz = cx / area_sum, cy / area_sum, cz / area_sum
        else:
            t = order[first[node]]
            cx, cy, cz = points[triangles[t, 0], 0], points[triangles[t, 0], 1], points[triangles[t, 0], 2]
        centre[node, 0], centre[node, 1], centre[node, 2] = cx, cy, cz
        area[node] = area_sum
        dipole[node, 0], dipole[node, 1], dipole[node, 2] = dx, dy, dz
        far = 0.0
        for r in range(3):
            for s in range(3):
                moment[node, r, s] = 0.0
        for m in range(first[node], last[node]):
            t = order[m]
            a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
            vx, vy, vz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
            n0, n1, n2 = 0.5 * (uy * vz - uz * vy), 0.5 * (uz * vx - ux * vz), 0.5 * (ux * vy - uy * vx)
            e0 = (points[a, 0] + points[b, 0] + points[c, 0]) / 3.0 - cx
            e1 = (points[a, 1] + points[b, 1] + points[c, 1]) / 3.0 - cy
            e2 = (points[a, 2] + points[b, 2] + points[c, 2]) / 3.0 - cz
            moment[node, 0, 0] += n0 * e0
            moment[node, 0, 1] += n0 * e1
            moment[node, 0, 2] += n0 * e2
            moment[node, 1, 0] += n1 * e0
            moment[node, 1, 1] += n1 * e1
            moment[node, 1, 2] += n1 * e2
            moment[node, 2, 0] += n2 * e0
            moment[node, 2, 1] += n2 * e1
            moment[node, 2, 2] += n2 * e2
            for corner in range(3):
                p = triangles[t, corner]
                ex, ey, ez = points[p, 0] - cx, points[p, 1] - cy, points[p, 2] - cz
                far = max(far, math.sqrt(ex * ex + ey * ey + ez * ez))
        radius[node] = far


@njit(cache=True, nogil=True, inline="always")
def _expansion(centre, dipole, moment, node, qx, qy, qz, distance2):
    """Solid angle of a node's triangles seen from ``q`` by the expansion of ``(x - q) / |x - q|^3`` about the
    node's centre: order 0 (the dipole ``sum A n``) and order 1 (the moment ``sum A n (c_t - centre)^T``)."""
    rx, ry, rz = centre[node, 0] - qx, centre[node, 1] - qy, centre[node, 2] - qz
    distance = math.sqrt(distance2)
    inv3 = 1.0 / (distance2 * distance)
    inv5 = inv3 / distance2
    order0 = (rx * dipole[node, 0] + ry * dipole[node, 1] + rz * dipole[node, 2]) * inv3
    trace = moment[node, 0, 0] + moment[node, 1, 1] + moment[node, 2, 2]
    quadratic = (rx * (moment[node, 0, 0] * rx + moment[node, 0, 1] * ry + moment[node, 0, 2] * rz)
                 + ry * (moment[node, 1, 0] * rx + moment[node, 1, 1] * ry + moment[node, 1, 2] * rz)
                 + rz * (moment[node, 2, 0] * rx + moment[node, 2, 1] * ry + moment[node, 2, 2] * rz))
    return order0 + trace * inv3 - 3.0 * quadratic * inv5


@njit(cache=True, nogil=True)
def tree_solid_angle(points, triangles, order, first, last, left, right, centre, radius, area, dipole, moment,
                     beta, qx, qy, qz, stack):
    """Sum of the triangles' solid angles seen from ``q``: nodes farther than ``beta`` radii by their expansion,
    leaves exactly. ``stack`` is scratch space (128 int64)."""
    stack[0] = 0
    top = 1
    total = 0.0
    while top > 0:
        top -= 1
        node = stack[top]
        dx, dy, dz = centre[node, 0] - qx, centre[node, 1] - qy, centre[node, 2] - qz
        distance2 = dx * dx + dy * dy + dz * dz
        far = beta * radius[node]
        if distance2 > far * far and distance2 > 0.0:
            total += _expansion(centre, dipole, moment, node, qx, qy, qz, distance2)
            continue
        if left[node] < 0:
            for m in range(first[node], last[node]):
                t = order[m]
                total += _solid_angle(points, triangles[t, 0], triangles[t, 1], triangles[t, 2], qx, qy, qz)
            continue
        stack[top] = left[node]
        stack[top + 1] = right[node]
        top += 2
    return total


@njit(cache=True, nogil=True, parallel=True)
def _tree_winding(points, triangles, order, first, last, left, right, centre, radius, area, dipole, moment, beta,
                  queries, out):
    for q in prange(queries.shape[0]):
        stack = np.empty(128, dtype=np.int64)
        total = tree_solid_angle(points, triangles, order, first, last, left, right, centre, radius, area, dipole,
                                 moment, beta, queries[q, 0], queries[q, 1], queries[q, 2], stack)
        out[q] = total / (4.0 * math.pi)


@njit(cache=True, nogil=True)
def _morton_order(centres, low, scale):
    """Triangle order along a 3D Morton (Z-order) curve of their centres on a 2^21 lattice."""
    codes = np.empty(centres.shape[0], dtype=np.int64)
    cells = np.empty(3, dtype=np.int64)
    for t in range(centres.shape[0]):
        code = 0
        for axis in range(3):
            value = int((centres[t, axis] - low[axis]) * scale)
            cells[axis] = min(max(value, 0), (1 << 21) - 1)
        for bit in range(21):
            for axis in range(3):
                code |= ((cells[axis] >> bit) & 1) << (3 * bit + axis)
        codes[t] = code
    return np.argsort(codes)


@dataclass(frozen=True)
class WindingTree:
    """Triangles grouped for fast winding numbers (Barill et al. 2018): a balanced binary tree over the
    triangles in Morton order, with each node's area-weighted centre, radius and dipole moments.

    Build with :meth:`build`; evaluate with :meth:`winding_numbers`.
    """

    points: np.ndarray
    triangles: np.ndarray
    order: np.ndarray
    first: np.ndarray
    last: np.ndarray
    left: np.ndarray
    right: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    area: np.ndarray
    dipole: np.ndarray
    moment: np.ndarray

    @classmethod
    def build(cls, points, triangles, *, leaf_size: int = LEAF_SIZE) -> "WindingTree":
        points, triangles = _as_mesh(points, triangles)
        if not np.all(np.isfinite(points)):
            raise ValueError("points must be finite (no NaN or infinite coordinates)")
        if len(triangles) == 0:
            raise ValueError("a winding tree needs at least one triangle")
        centres = points[triangles].mean(axis=1)
        low = centres.min(axis=0)
        extent = float((centres.max(axis=0) - low).max())
        scale = ((1 << 21) - 1) / extent if extent > 0 else 0.0
        order = _morton_order(centres, low, scale).astype(np.int64)
        first, last, left, right = _build_nodes(len(triangles), int(leaf_size))
        nodes = len(first)
        centre = np.empty((nodes, 3))
        radius = np.empty(nodes)
        area = np.empty(nodes)
        dipole = np.empty((nodes, 3))
        moment = np.empty((nodes, 3, 3))
        _node_moments(points, triangles, order, first, last, centre, radius, area, dipole, moment)
        return cls(points, triangles, order, first, last, left, right, centre, radius, area, dipole, moment)

    def arrays(self) -> tuple:
        """The tree as the tuple of arrays the kernels take (points first, moment last)."""
        return self._arrays()

    def _arrays(self) -> tuple:
        return (self.points, self.triangles, self.order, self.first, self.last, self.left, self.right, self.centre,
                self.radius, self.area, self.dipole, self.moment)

    @property
    def nodes(self) -> int:
        return int(len(self.first))

    def winding_numbers(self, queries, *, beta: float = DEFAULT_BETA, progress: ProgressCallback = None,
                        chunk: int = 65536) -> np.ndarray:
        """Generalised winding numbers ``(k,)`` at ``queries`` ``(k, 3)`` mm; ``beta`` > 1 is the far-field criterion
        (larger: more accurate and slower)."""
        if not beta > 1.0:
            raise ValueError(f"beta must be more than 1 (node radii a query must be away to expand), got {beta}")
        queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float64)
        if queries.ndim != 2 or queries.shape[1] != 3:
            raise ValueError(f"queries must be a (k, 3) array, got shape {queries.shape}")
        out = np.empty(len(queries), dtype=np.float64)
        for start in range(0, len(queries), chunk):
            stop = min(start + chunk, len(queries))
            _tree_winding(*self._arrays(), float(beta), queries[start:stop], out[start:stop])
            report(progress, stop / len(queries))
        return out


def winding_numbers(points, triangles, queries, *, beta: float = DEFAULT_BETA) -> np.ndarray:
    """Fast generalised winding numbers ``(k,)`` of the mesh at ``queries`` ``(k, 3)`` (see :class:`WindingTree`)."""
    return WindingTree.build(points, triangles).winding_numbers(queries, beta=beta)


# ----------------------------------------------------------------------------------------------------------------
# Closing a mesh as a chain
# ----------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BoundaryCaps:
    """Fans closing the boundary of a mesh: ``triangles`` index ``points`` (the mesh's points followed by one apex
    per boundary component); triangle ``t`` is ``(a, b, apex)`` over the rim edge ``a -> b`` of cap
    ``piece[t]``; per cap its ``centre`` (the apex), ``radius`` (mm, enclosing its triangles), ``area`` (mm^2)
    and rim ``length`` (mm); ``edges`` is the number of boundary edges (counted with multiplicity)."""

    points: np.ndarray
    triangles: np.ndarray
    piece: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    area: np.ndarray
    length: np.ndarray
    edges: int

    @property
    def count(self) -> int:
        return int(len(self.area))


def boundary_caps(points, triangles) -> BoundaryCaps:
    """A fan over each connected piece of the mesh's boundary chain, oriented so mesh plus fans is closed.

    The boundary chain is every edge the triangles do not use equally often in both directions (a hole's rim, a
    fin, a seam where the orientation flips), with the surplus as multiplicity. Each fan joins the edges of one
    connected piece of that chain to the mean of its vertices, reversed, so every edge of mesh plus fans is used
    as often in one direction as in the other: the signed crossings of any line with it then sum to zero, and
    its winding number is an integer everywhere.
    """
    points, triangles = _as_mesh(points, triangles)
    n = len(points)
    empty = BoundaryCaps(points, np.empty((0, 3), np.int64), np.empty(0, np.int64), np.empty((0, 3)), np.empty(0),
                         np.empty(0), np.empty(0), 0)
    if len(triangles) == 0:
        return empty
    start = triangles.reshape(-1)
    end = triangles[:, [1, 2, 0]].reshape(-1)
    low, high = np.minimum(start, end), np.maximum(start, end)
    keys, inverse = np.unique(low * np.int64(n) + high, return_inverse=True)
    net = np.bincount(inverse.reshape(-1), weights=np.where(start < end, 1, -1), minlength=len(keys))
    net = np.rint(net).astype(np.int64)
    chain = np.flatnonzero(net != 0)
    if chain.size == 0:
        return empty
    lo, hi, surplus = keys[chain] // n, keys[chain] % n, net[chain]
    # The mesh's boundary runs lo -> hi where surplus > 0; the cap must run it the other way.
    a = np.where(surplus > 0, hi, lo)
    b = np.where(surplus > 0, lo, hi)
    repeat = np.abs(surplus)
    a, b = np.repeat(a, repeat), np.repeat(b, repeat)
    vertices, local = np.unique(np.concatenate([a, b]), return_inverse=True)
    graph = sparse.coo_matrix((np.ones(len(a)), (local[:len(a)], local[len(a):])),
                              shape=(len(vertices), len(vertices)))
    pieces, labels = connected_components(graph, directed=False)
    apex = np.zeros((pieces, 3))
    np.add.at(apex, labels, points[vertices])
    apex /= np.bincount(labels, minlength=pieces)[:, None]
    piece_of_edge = labels[local[:len(a)]]
    cap_triangles = np.stack([a, b, n + piece_of_edge], axis=1).astype(np.int64)
    all_points = np.concatenate([points, apex])
    corners = all_points[cap_triangles]
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    area = np.bincount(piece_of_edge, weights=areas, minlength=pieces)
    distance = np.linalg.norm(corners - apex[piece_of_edge][:, None, :], axis=2).max(axis=1)
    radius = np.zeros(pieces)
    np.maximum.at(radius, piece_of_edge, distance)
    rim = np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1)
    length = np.bincount(piece_of_edge, weights=rim, minlength=pieces)
    return BoundaryCaps(all_points, cap_triangles, piece_of_edge.astype(np.int64), apex, radius, area, length,
                        int(len(a)))
