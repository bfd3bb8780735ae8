"""The exact Euclidean feature transform of a set of sites on a grid: for every voxel, the flat index of its
nearest site (ties aside), with the grid's own, possibly anisotropic, spacing. The distance propagation
(:mod:`.propagate`) uses it on its coarsest level to hand every voxel the nearest band voxel.

Separable, one pass per axis (Felzenszwalb and Huttenlocher 2012; Meijster et al. 2000): along each line the
squared distance to the nearest site is the lower envelope of parabolas ``f[p] + (x - p h)^2`` rooted at the
values the previous pass left. Each pass handles whole lines in parallel, the threads taking slices (or columns)
one at a time from a shared counter (:func:`algorithms.common.atomics.take`).

Arrays are ``(nz, ny, nx)``; ``work`` (float32) holds squared mm, ``site`` (int32) flat indices. Call
:func:`feature_rows`, :func:`feature_columns`, :func:`feature_slices` in this order.

References
----------
P. F. Felzenszwalb, D. P. Huttenlocher, "Distance transforms of sampled functions", Theory of Computing 8, 2012.
A. Meijster, J. B. T. M. Roerdink, W. H. Hesselink, "A general algorithm for computing distance transforms in
linear time", Mathematical Morphology and its Applications to Image and Signal Processing, 2000.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ...common.atomics import take

__all__ = ["feature_columns", "feature_rows", "feature_slices"]


@njit(cache=True, nogil=True)
def _envelope(f, site, n, h, v, z, out_f, out_site):
    """1-D squared distance transform of ``f`` (``inf``: no site) on positions ``q h``: ``out_f[q] = min_p f[p] +
    (q h - p h)^2`` and ``out_site[q]`` = ``site`` of the minimising ``p`` (the lower envelope of parabolas,
    Felzenszwalb and Huttenlocher); ``v`` (n) and ``z`` (n + 1) are work space. Returns False when no site."""
    top = -1
    for q in range(n):
        fq = f[q]
        if fq == np.inf:
            continue
        xq = q * h
        while top >= 0:
            p = v[top]
            xp = p * h
            s = ((fq + xq * xq) - (f[p] + xp * xp)) / (2.0 * (xq - xp))
            if s <= z[top]:
                top -= 1
            else:
                top += 1
                v[top] = q
                z[top] = s
                break
        if top < 0:
            top = 0
            v[0] = q
            z[0] = -np.inf
    if top < 0:
        return False
    z[top + 1] = np.inf
    c = 0
    for q in range(n):
        x = q * h
        while z[c + 1] < x:
            c += 1
        p = v[c]
        out_f[q] = (x - p * h) ** 2 + f[p]
        out_site[q] = site[p]
    return True


@njit(cache=True, nogil=True)
def _line_workspace(n):
    """Work arrays of one :func:`_line_pass` on a line of ``n`` samples: values, sites, parabola positions,
    boundaries (n + 1), output values, output sites."""
    return (np.empty(n), np.empty(n, dtype=np.int32), np.empty(n, dtype=np.int64), np.empty(n + 1), np.empty(n),
            np.empty(n, dtype=np.int32))


@njit(cache=True, nogil=True)
def _line_pass(f_in, site_in, h, workspace, f_out, site_out):
    """One line of a pass: the transform of ``f_in`` / ``site_in`` (read whole first, so they may be ``f_out`` /
    ``site_out`` themselves) into ``f_out`` / ``site_out``; ``inf`` and -1 where the line has no site."""
    f, s, v, z, out_f, out_s = workspace
    n = f_in.shape[0]
    for q in range(n):
        f[q] = f_in[q]
        s[q] = site_in[q]
    if _envelope(f, s, n, h, v, z, out_f, out_s):
        for q in range(n):
            f_out[q] = out_f[q]
            site_out[q] = out_s[q]
    else:
        for q in range(n):
            f_out[q] = np.inf
            site_out[q] = -1


@njit(cache=True, nogil=True, parallel=True)
def feature_rows(best, band2, sx, work, site, parts):
    """Pass along i, the sites being the voxels with ``best <= band2``: ``work`` = squared distance (mm^2) to the
    nearest site of the row, ``site`` its flat index (-1 where the row has none); slices in parallel."""
    nz, ny, nx = best.shape
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # k taken from a shared counter
        workspace = _line_workspace(nx)
        while True:
            k = take(queue, 1)
            if k >= nz:
                break
            for j in range(ny):
                base = (k * ny + j) * nx
                for i in range(nx):
                    work[k, j, i] = 0.0 if best[k, j, i] <= band2 else np.inf
                    site[k, j, i] = base + i
                _line_pass(work[k, j], site[k, j], sx, workspace, work[k, j], site[k, j])


@njit(cache=True, nogil=True, parallel=True)
def feature_columns(work, site, sy, parts):
    """Pass along j, in place on ``work`` and ``site``; slices in parallel."""
    nz, ny, nx = work.shape
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # k taken from a shared counter
        workspace = _line_workspace(ny)
        while True:
            k = take(queue, 1)
            if k >= nz:
                break
            for i in range(nx):
                _line_pass(work[k, :, i], site[k, :, i], sy, workspace, work[k, :, i], site[k, :, i])


@njit(cache=True, nogil=True, parallel=True)
def feature_slices(work, site, sz, parts):
    """Pass along k: ``site`` becomes the flat index of each voxel's nearest site (-1: none); columns (fixed j) in
    parallel, a whole (k, i) plane at a time, transformed in a copy (lines along k contiguous)."""
    nz, ny, nx = work.shape
    queue = np.zeros(1, dtype=np.int64)
    for _part in prange(parts):  # j taken from a shared counter
        workspace = _line_workspace(nz)
        f_plane = np.empty((nx, nz), dtype=np.float32)  # as ``work``: _line_pass is compiled for float32 lines
        s_plane = np.empty((nx, nz), dtype=np.int32)
        while True:
            j = take(queue, 1)
            if j >= ny:
                break
            for k in range(nz):
                for i in range(nx):
                    f_plane[i, k] = work[k, j, i]
                    s_plane[i, k] = site[k, j, i]
            for i in range(nx):
                _line_pass(f_plane[i], s_plane[i], sz, workspace, f_plane[i], s_plane[i])
            for k in range(nz):
                for i in range(nx):
                    site[k, j, i] = s_plane[i, k]
