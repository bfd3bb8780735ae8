"""numba kernels that threshold ``n - w_caps`` at 1/2 on a grid, examining cubes of voxels from coarse to fine.

Used by :func:`algorithms.fields.voxelise.voxelise` with ``inside="winding"`` (see the method there): ``levels``
holds the integer winding number ``n`` of mesh plus fans, and the mesh's own winding number is ``n - w_caps``,
where ``w_caps`` is that of the fans (:func:`.core.boundary_caps`). Wherever ``|w_caps| < 1/2``, ``n - w_caps
>= 1/2`` exactly when ``n >= 1``, so only the voxels where the fans' winding number may reach 1/2 need it.

A cube of voxels is skipped when the fans' winding number at its centre (the fans' tree, Barill et al.'s far-field
expansion) plus its radius times a bound on the gradient stays below ``1/2 - margin``. The gradient of a surface's
winding number away from the surface depends only on its rim (the Biot-Savart form of the solid angle,
``grad Omega = loop integral of dl x (x - q) / |x - q|^3``), so ``|grad w| <= sum over rim edges of
length / (4 pi d^2)``; the bound holds only in a cube that no fan triangle enters (the winding number jumps across
the fan), which is tested exactly. Other cubes are split in eight, down to single voxels, whose level becomes 1
if ``n - w_caps >= 1/2`` and 0 otherwise.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .core import tree_solid_angle


@njit(cache=True, nogil=True, forceinline=True)
def _dot(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


@njit(cache=True, nogil=True)
def _triangle_distance(points, a, b, c, px, py, pz):
    """Distance from ``p`` to triangle ``(a, b, c)`` (closest point by Voronoi regions of the corners and edges)."""
    ax, ay, az = points[a, 0], points[a, 1], points[a, 2]
    abx, aby, abz = points[b, 0] - ax, points[b, 1] - ay, points[b, 2] - az
    acx, acy, acz = points[c, 0] - ax, points[c, 1] - ay, points[c, 2] - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = _dot(abx, aby, abz, apx, apy, apz)
    d2 = _dot(acx, acy, acz, apx, apy, apz)
    if d1 <= 0.0 and d2 <= 0.0:
        return math.sqrt(_dot(apx, apy, apz, apx, apy, apz))
    bpx, bpy, bpz = px - points[b, 0], py - points[b, 1], pz - points[b, 2]
    d3 = _dot(abx, aby, abz, bpx, bpy, bpz)
    d4 = _dot(acx, acy, acz, bpx, bpy, bpz)
    if d3 >= 0.0 and d4 <= d3:
        return math.sqrt(_dot(bpx, bpy, bpz, bpx, bpy, bpz))
    cpx, cpy, cpz = px - points[c, 0], py - points[c, 1], pz - points[c, 2]
    d5 = _dot(abx, aby, abz, cpx, cpy, cpz)
    d6 = _dot(acx, acy, acz, cpx, cpy, cpz)
    if d6 >= 0.0 and d5 <= d6:
        return math.sqrt(_dot(cpx, cpy, cpz, cpx, cpy, cpz))
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        qx, qy, qz = ax + t * abx, ay + t * aby, az + t * abz
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        qx, qy, qz = ax + t * acx, ay + t * acy, az + t * acz
    elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        bx, by, bz = points[b, 0], points[b, 1], points[b, 2]
        qx = bx + t * (points[c, 0] - bx)
        qy = by + t * (points[c, 1] - by)
        qz = bz + t * (points[c, 2] - bz)
    else:
        total = va + vb + vc
        if total == 0.0:  # a degenerate triangle: its closest corner is close enough for a lower bound test
            return min(math.sqrt(_dot(apx, apy, apz, apx, apy, apz)),
                       min(math.sqrt(_dot(bpx, bpy, bpz, bpx, bpy, bpz)),
                           math.sqrt(_dot(cpx, cpy, cpz, cpx, cpy, cpz))))
        v = vb / total
        w = vc / total
        qx, qy, qz = ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w
    dx, dy, dz = px - qx, py - qy, pz - qz
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True)
def _touches(points, triangles, order, first, last, left, right, centre, radius, qx, qy, qz, reach, stack):
    """Whether any triangle of the tree comes within ``reach`` of ``q``."""
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        dx, dy, dz = centre[node, 0] - qx, centre[node, 1] - qy, centre[node, 2] - qz
        if math.sqrt(dx * dx + dy * dy + dz * dz) > radius[node] + reach:
            continue
        if left[node] < 0:
            for m in range(first[node], last[node]):
                t = order[m]
                if _triangle_distance(points, triangles[t, 0], triangles[t, 1], triangles[t, 2], qx, qy,
                                      qz) <= reach:
                    return True
            continue
        stack[top] = left[node]
        stack[top + 1] = right[node]
        top += 2
    return False


@njit(cache=True, nogil=True)
def _segment_distance(points, a, b, px, py, pz):
    ax, ay, az = points[a, 0], points[a, 1], points[a, 2]
    ux, uy, uz = points[b, 0] - ax, points[b, 1] - ay, points[b, 2] - az
    length2 = ux * ux + uy * uy + uz * uz
    t = 0.0
    if length2 > 0.0:
        t = min(max(((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / length2, 0.0), 1.0)
    dx, dy, dz = px - ax - t * ux, py - ay - t * uy, pz - az - t * uz
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True)
def _rim_gradient(points, rims, rim_start, cap_centre, cap_radius, cap_length, qx, qy, qz, reach):
    """Bound on ``|grad w_caps|`` over the ball of radius ``reach`` around ``q`` (which no fan triangle enters):
    ``sum length / (4 pi d^2)`` over the rims, a whole cap at once when its ball is far, else edge by edge."""
    total = 0.0
    for cap in range(cap_centre.shape[0]):
        dx, dy, dz = cap_centre[cap, 0] - qx, cap_centre[cap, 1] - qy, cap_centre[cap, 2] - qz
        gap = math.sqrt(dx * dx + dy * dy + dz * dz) - cap_radius[cap] - reach
        if gap > cap_radius[cap]:
            total += cap_length[cap] / (gap * gap)
            continue
        for e in range(rim_start[cap], rim_start[cap + 1]):
            a, b = rims[e, 0], rims[e, 1]
            d = _segment_distance(points, a, b, qx, qy, qz) - reach
            if d <= 0.0:
                return math.inf
            ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
            total += math.sqrt(ux * ux + uy * uy + uz * uz) / (d * d)
    return total / (4.0 * math.pi)


@njit(cache=True, nogil=True, parallel=True)
def threshold_blocks(points, triangles, order, first, last, left, right, centre, radius, area, dipole, moment,
                     rims, rim_start, cap_centre, cap_radius, cap_length, beta, affine, levels, blocks, margin,
                     evaluated):
    """Threshold ``levels - w_caps`` at 1/2 inside the cubes ``blocks`` (rows ``(i0, j0, k0, size)``) where needed.

    The first twelve arguments are the fans' :class:`.core.WindingTree`; ``rims`` ``(E, 2)`` are the rim edges
    sorted by cap with CSR ``rim_start``; per cap its centre, radius and rim length; ``affine`` takes
    ``(i, j, k, 1)`` to mm. ``levels`` (int8) is changed in place; ``evaluated[b]`` receives the voxels cube ``b``
    decided one by one. Cubes must not overlap.
    """
    nz, ny, nx = levels.shape
    four_pi = 4.0 * math.pi
    step = np.empty(3)
    for axis in range(3):
        step[axis] = math.sqrt(affine[0, axis] ** 2 + affine[1, axis] ** 2 + affine[2, axis] ** 2)
    for b in prange(blocks.shape[0]):
        stack = np.empty(128, dtype=np.int64)
        pending = np.empty((512, 6), dtype=np.int64)  # (i0, i1, j0, j1, k0, k1), ends excluded
        pending[0, 0], pending[0, 1] = blocks[b, 0], min(blocks[b, 0] + blocks[b, 3], nx)
        pending[0, 2], pending[0, 3] = blocks[b, 1], min(blocks[b, 1] + blocks[b, 3], ny)
        pending[0, 4], pending[0, 5] = blocks[b, 2], min(blocks[b, 2] + blocks[b, 3], nz)
        top = 1
        count = 0
        while top > 0:
            top -= 1
            i0, i1, j0, j1 = pending[top, 0], pending[top, 1], pending[top, 2], pending[top, 3]
            k0, k1 = pending[top, 4], pending[top, 5]
            if i0 >= i1 or j0 >= j1 or k0 >= k1:
                continue
            ci, cj, ck = 0.5 * (i0 + i1 - 1), 0.5 * (j0 + j1 - 1), 0.5 * (k0 + k1 - 1)
            qx = affine[0, 0] * ci + affine[0, 1] * cj + affine[0, 2] * ck + affine[0, 3]
            qy = affine[1, 0] * ci + affine[1, 1] * cj + affine[1, 2] * ck + affine[1, 3]
            qz = affine[2, 0] * ci + affine[2, 1] * cj + affine[2, 2] * ck + affine[2, 3]
            reach = 0.5 * math.sqrt(((i1 - i0 - 1) * step[0]) ** 2 + ((j1 - j0 - 1) * step[1]) ** 2
                                    + ((k1 - k0 - 1) * step[2]) ** 2)
            if reach == 0.0:
                # One voxel: decide it. The row kernel counted a crossing exactly at the centre as behind it (the
                # centre moved by +e' along i, then +e, +e^2 along j, k); evaluate the fans on that side too, so a
                # centre lying exactly on a fan gets the fans' winding number that goes with its level.
                for axis in range(3):
                    nudge = affine[axis, 0] * 1e-7 + affine[axis, 1] * 1e-9 + affine[axis, 2] * 1e-11
                    if axis == 0:
                        qx += nudge
                    elif axis == 1:
                        qy += nudge
                    else:
                        qz += nudge
            w = tree_solid_angle(points, triangles, order, first, last, left, right, centre, radius, area, dipole,
                                 moment, beta, qx, qy, qz, stack) / four_pi
            if reach == 0.0:
                level = levels[k0, j0, i0]
                levels[k0, j0, i0] = 1 if level - w >= 0.5 else 0
                count += 1
                continue
            if abs(w) < 0.5 - margin and not _touches(points, triangles, order, first, last, left, right, centre,
                                                      radius, qx, qy, qz, reach, stack):
                gradient = _rim_gradient(points, rims, rim_start, cap_centre, cap_radius, cap_length, qx, qy, qz,
                                         reach)
                if abs(w) + reach * gradient < 0.5 - margin:
                    continue  # |w_caps| < 1/2 everywhere in the cube: n >= 1 decides there
            mi, mj, mk = i0 + (i1 - i0 + 1) // 2, j0 + (j1 - j0 + 1) // 2, k0 + (k1 - k0 + 1) // 2
            for a0, a1 in ((k0, mk), (mk, k1)):
                for b0, b1 in ((j0, mj), (mj, j1)):
                    for c0, c1 in ((i0, mi), (mi, i1)):
                        if c0 < c1 and b0 < b1 and a0 < a1:
                            pending[top, 0], pending[top, 1], pending[top, 2] = c0, c1, b0
                            pending[top, 3], pending[top, 4], pending[top, 5] = b1, a0, a1
                            top += 1
        evaluated[b] = count
