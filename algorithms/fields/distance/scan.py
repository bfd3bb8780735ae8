"""numba kernels that scan the regions of :mod:`.kernels` into the grid, slab by slab and slice by slice.

The grid's slices are grouped into slabs of a few slices; every region lists the slabs it meets (the source's
"active" triangles of a slice, sorted by height), so a region's half-spaces are built once per slab. Within a slice
the region's cross-section is a convex polygon: the kernel takes the polygon's x and y extent from the region's hull
points and then visits it along rows (runs along i) or columns (runs along j), whichever gives fewer lines, each
run clipped to the region's half-spaces (and ball). Along a run the frame coordinates of the owner triangle change
linearly, so each voxel costs the source's region test and a few multiplications. Slabs run in parallel; a slab
is written by one thread only.

Coordinates: the grid's frame in mm, voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)``; arrays ``(nz, ny, nx)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .kernels import (CUBE, CUBE_EDGES, MAX_PLANES, MAX_VERTICES, PRISM, PRISM_EDGES, PYRAMID, WEDGE_EDGES,
                                build_polytope, frame_distance2)


@njit(cache=True, nogil=True)
def slab_lists(first, last, slab, n_slabs):
    """CSR lists of the regions meeting each slab of ``slab`` slices: ``members[start[s]:start[s + 1]]``."""
    start = np.zeros(n_slabs + 1, dtype=np.int64)
    for pid in range(first.shape[0]):
        if last[pid] < first[pid]:
            continue
        for s in range(first[pid] // slab, last[pid] // slab + 1):
            start[s + 1] += 1
    for s in range(n_slabs):
        start[s + 1] += start[s]
    fill = start[:-1].copy()
    members = np.empty(start[n_slabs], dtype=np.int32)
    for pid in range(first.shape[0]):
        if last[pid] < first[pid]:
            continue
        for s in range(first[pid] // slab, last[pid] // slab + 1):
            members[fill[s]] = pid
            fill[s] += 1
    return start, members


@njit(cache=True, nogil=True)
def _cross(vertices, p, q, z, extent):
    zp = vertices[p, 2] - z
    zq = vertices[q, 2] - z
    if (zp < 0.0 < zq) or (zq < 0.0 < zp):
        f = zp / (zp - zq)
        x = vertices[p, 0] + f * (vertices[q, 0] - vertices[p, 0])
        y = vertices[p, 1] + f * (vertices[q, 1] - vertices[p, 1])
        extent[0] = min(extent[0], x)
        extent[1] = max(extent[1], x)
        extent[2] = min(extent[2], y)
        extent[3] = max(extent[3], y)


@njit(cache=True, nogil=True)
def _section(vertices, nv, shape, z, zlow, zhigh, pad, extent):
    """The x and y extent (mm) of the hull of ``vertices`` (connected as ``shape`` says) on the plane at height
    ``z`` into ``extent`` (xlow, xhigh, ylow, yhigh); False when the plane misses it."""
    if z < zlow - pad or z > zhigh + pad:
        return False
    z = min(max(z, zlow), zhigh)
    extent[0] = np.inf
    extent[1] = -np.inf
    extent[2] = np.inf
    extent[3] = -np.inf
    for p in range(nv):
        if vertices[p, 2] == z:
            extent[0] = min(extent[0], vertices[p, 0])
            extent[1] = max(extent[1], vertices[p, 0])
            extent[2] = min(extent[2], vertices[p, 1])
            extent[3] = max(extent[3], vertices[p, 1])
    if shape == PYRAMID:  # apex 0 to every base point, and every chord of the (planar) base
        apex = np.int64(0)  # not a literal 0: numba would compile _cross for it as well as for int64
        for q in range(1, nv):
            _cross(vertices, apex, q, z, extent)
            for r in range(q + 1, nv):
                _cross(vertices, q, r, z, extent)
    else:
        edges = PRISM_EDGES if shape == PRISM else (CUBE_EDGES if shape == CUBE else WEDGE_EDGES)
        for e in range(edges.shape[0]):
            _cross(vertices, edges[e, 0], edges[e, 1], z, extent)
    extent[0] -= pad
    extent[1] += pad
    extent[2] -= pad
    extent[3] += pad
    return extent[0] <= extent[1]


@njit(cache=True, nogil=True)
def _prepare_lines(planes, n_planes, sphere, axis, z, bounds):
    """Per plane, for lines along ``axis`` in the slice at ``z``: ``bounds[p] = (kind, 1 / coefficient, rhs at
    w = 0, slope in w)``: kind +1 an upper bound, -1 a lower bound, 0 a plane parallel to the lines (a test)."""
    other = 1 - axis
    for p in range(n_planes):
        coefficient = planes[p, axis]
        bounds[p, 2] = planes[p, 3] - planes[p, 2] * z
        bounds[p, 3] = planes[p, other]
        if coefficient > 1e-12:
            bounds[p, 0] = 1.0
            bounds[p, 1] = 1.0 / coefficient
        elif coefficient < -1e-12:
            bounds[p, 0] = -1.0
            bounds[p, 1] = 1.0 / coefficient
        else:
            bounds[p, 0] = 0.0
            bounds[p, 1] = 0.0


@njit(cache=True, nogil=True)
def _run(bounds, n_planes, sphere, axis, w, z, step, size):
    """The voxels ``[first, last]`` of the line along ``axis`` (0: x, 1: y) at the other coordinate ``w`` and
    height ``z`` that lie in the region (``last < first`` when none)."""
    low = -np.inf
    high = np.inf
    for p in range(n_planes):
        rhs = bounds[p, 2] - bounds[p, 3] * w
        kind = bounds[p, 0]
        if kind > 0.0:
            high = min(high, rhs * bounds[p, 1])
        elif kind < 0.0:
            low = max(low, rhs * bounds[p, 1])
        elif rhs < 0.0:
            return 1, 0
    if sphere[3] >= 0.0:
        other = 1 - axis
        rest = sphere[3] - (w - sphere[other]) ** 2 - (z - sphere[2]) ** 2
        if rest < 0.0:
            return 1, 0
        rest = np.sqrt(rest)
        low = max(low, sphere[axis] - rest)
        high = min(high, sphere[axis] + rest)
    if low > high:
        return 1, 0
    first = max(int(np.ceil(low / step)), 0) if low > -1e300 else 0
    last = min(int(np.floor(high / step)), size - 1) if high < 1e300 else size - 1
    return first, last


@njit(cache=True, nogil=True, parallel=True)
def scan_slabs(order, slab, start, members, n_triangles, tri_kind, frames, frame_vertices, points, wedges,
               wedge_vertices, cone_info, cone_start, cone_rays, cone_edges, reach, slack, spacing, best, nearest,
               counts):
    """For the slabs ``order`` (in parallel): every voxel of every region meeting the slab gets the distance to the
    region's triangle when that is smaller than what it holds: ``best`` (squared mm, float32) and ``nearest``
    (triangle index). ``counts[s]`` gets the distances computed and the lines visited in slab ``s``."""
    nz, ny, nx = best.shape
    sz = spacing[2]
    for c in prange(order.shape[0]):
        s = order[c]
        k_first = s * slab
        k_last = min(k_first + slab, nz) - 1
        planes = np.empty((MAX_PLANES, 4))
        vertices = np.empty((MAX_VERTICES, 3))
        sphere = np.empty(4)
        extent = np.empty(4)
        bounds = np.empty((MAX_PLANES, 4))
        evaluations = 0
        lines = 0
        for m in range(start[s], start[s + 1]):
            pid = np.int64(members[m])  # int64, as polytope_slices passes it: one compiled build_polytope
            owner, n_planes, nv, shape = build_polytope(pid, n_triangles, tri_kind, frames, frame_vertices, points,
                                                        wedges, wedge_vertices, cone_info, cone_start, cone_rays,
                                                        cone_edges, reach, slack, planes, vertices, sphere)
            zlow = np.inf
            zhigh = -np.inf
            for q in range(nv):
                zlow = min(zlow, vertices[q, 2])
                zhigh = max(zhigh, vertices[q, 2])
            k0 = max(k_first, int(np.ceil((zlow - slack) / sz)))
            k1 = min(k_last, int(np.floor((zhigh + slack) / sz)))
            ox, oy, oz = frames[owner, 0], frames[owner, 1], frames[owner, 2]
            a, b, h = frames[owner, 12], frames[owner, 13], frames[owner, 14]
            for k in range(k0, k1 + 1):
                z = k * sz
                if not _section(vertices, nv, shape, z, zlow, zhigh, slack, extent):
                    continue
                i0 = max(int(np.ceil(extent[0] / spacing[0])), 0)
                i1 = min(int(np.floor(extent[1] / spacing[0])), nx - 1)
                j0 = max(int(np.ceil(extent[2] / spacing[1])), 0)
                j1 = min(int(np.floor(extent[3] / spacing[1])), ny - 1)
                if i0 > i1 or j0 > j1:
                    continue
                axis = 0 if j1 - j0 <= i1 - i0 else 1  # rows (runs along i) or columns (runs along j)
                other = 1 - axis
                line_first = j0 if axis == 0 else i0
                line_last = j1 if axis == 0 else i1
                step = spacing[axis]
                dz = z - oz
                dr = step * frames[owner, 3 + axis]
                ds = step * frames[owner, 6 + axis]
                dt = step * frames[owner, 9 + axis]
                _prepare_lines(planes, n_planes, sphere, axis, z, bounds)
                for line in range(line_first, line_last + 1):
                    w = line * spacing[other]
                    first, last = _run(bounds, n_planes, sphere, axis, w, z, step, nx if axis == 0 else ny)
                    lines += 1
                    if first > last:
                        continue
                    # frame coordinates at the line's start and their steps along it (the source's interpolated
                    # texture coordinates)
                    if axis == 0:
                        px, py = -ox, w - oy
                    else:
                        px, py = w - ox, -oy
                    r0 = px * frames[owner, 3] + py * frames[owner, 4] + dz * frames[owner, 5]
                    s0 = px * frames[owner, 6] + py * frames[owner, 7] + dz * frames[owner, 8]
                    t0 = px * frames[owner, 9] + py * frames[owner, 10] + dz * frames[owner, 11]
                    evaluations += last - first + 1
                    if axis == 0:
                        row_best = best[k, line]
                        row_nearest = nearest[k, line]
                        for i in range(first, last + 1):
                            d2 = frame_distance2(r0 + i * dr, s0 + i * ds, t0 + i * dt, a, b, h)
                            if d2 < row_best[i]:
                                row_best[i] = d2
                                row_nearest[i] = owner
                    else:
                        for j in range(first, last + 1):
                            d2 = frame_distance2(r0 + j * dr, s0 + j * ds, t0 + j * dt, a, b, h)
                            if d2 < best[k, j, line]:
                                best[k, j, line] = d2
                                nearest[k, j, line] = owner
        counts[s, 0] += evaluations
        counts[s, 1] += lines
