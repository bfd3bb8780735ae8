"""Where along a ray cut-away tools can matter: per-ray bounds, keep clips and removed chords (issue 15).

Before its first sample, a ray (in shear-warp: a line of samples of one slice) meets every tool once, in the tool's
own frame, where it stays a line; the renderers then test the tools (:mod:`algorithms.common.cutaway`) only on the
part of the ray within the test margin of some tool, clip the ray to the inside of every ``keep`` tool and jump the
longest chord through a ``remove`` shape at once. All three are exact: the image equals the per-sample test of
source 002 (Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009, section 2.5) at
every sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cutaway import BINARY, BOX, CYLINDER, GRID, HALFSPACE, REMOVE, SPHERE, to_tool


@njit(cache=True, nogil=True, forceinline=True)
def _slab(o, d, low, high, t0, t1):
    """The part ``[t0, t1]`` of the line ``o + t d`` (one coordinate) with ``low <= o + t d <= high``."""
    if d == 0.0:
        if o < low or o > high:
            return 1.0, 0.0
        return t0, t1
    a = (low - o) / d
    b = (high - o) / d
    if a > b:
        a, b = b, a
    return max(t0, a), min(t1, b)


@njit(cache=True, nogil=True, forceinline=True)
def _disc(ax, ay, az, bx, by, bz, radius, t0, t1):
    """The part ``[t0, t1]`` of the line ``a + t b`` with ``|a + t b| <= radius`` (``bz = az = 0``: a cylinder)."""
    qa = bx * bx + by * by + bz * bz
    qb = ax * bx + ay * by + az * bz
    qc = ax * ax + ay * ay + az * az - radius * radius
    if qa == 0.0:
        return (t0, t1) if qc <= 0.0 else (1.0, 0.0)
    discriminant = qb * qb - qa * qc
    if discriminant < 0.0:
        return 1.0, 0.0
    root = math.sqrt(discriminant)
    return max(t0, (-qb - root) / qa), min(t1, (-qb + root) / qa)


#: Slack added to the bounds (tool units) against rounding: a point this close outside still counts as inside.
_BOUNDS_SLACK = 1.0e-6


@njit(cache=True, nogil=True, forceinline=True)
def _shape_span(kind, p0, p1, p2, n0, n1, n2, ax, ay, az, bx, by, bz, grow):
    """The part of the line ``a + t b`` (tool frame) inside the tool's shape (parameters ``p0..p2``; grid size
    ``n0..n2``) grown by ``grow`` (tool units; a negative ``grow`` shrinks it), a grid tool's grid box whatever
    ``grow``; ``t0 > t1`` when it misses."""
    t0, t1 = -np.inf, np.inf
    if kind == SPHERE:
        if p0 + grow <= 0.0:
            return 1.0, 0.0
        t0, t1 = _disc(ax, ay, az, bx, by, bz, p0 + grow, t0, t1)
    elif kind == CYLINDER:
        if p0 + grow <= 0.0:
            return 1.0, 0.0
        t0, t1 = _disc(ax, ay, 0.0, bx, by, 0.0, p0 + grow, t0, t1)
        t0, t1 = _slab(az, bz, -p1 - grow, p1 + grow, t0, t1)
    elif kind == BOX:
        t0, t1 = _slab(ax, bx, -p0 - grow, p0 + grow, t0, t1)
        t0, t1 = _slab(ay, by, -p1 - grow, p1 + grow, t0, t1)
        t0, t1 = _slab(az, bz, -p2 - grow, p2 + grow, t0, t1)
    elif kind == HALFSPACE:
        t0, t1 = _slab(az, bz, -grow, np.inf, t0, t1)
    else:  # a grid: FAR outside its voxel centres
        t0, t1 = _slab(ax, bx, -_BOUNDS_SLACK, n0 - 1 + _BOUNDS_SLACK, t0, t1)
        t0, t1 = _slab(ay, by, -_BOUNDS_SLACK, n1 - 1 + _BOUNDS_SLACK, t0, t1)
        t0, t1 = _slab(az, bz, -_BOUNDS_SLACK, n2 - 1 + _BOUNDS_SLACK, t0, t1)
    return t0, t1


@njit(cache=True, nogil=True, inline="always")
def ray_interval(tools, ox, oy, oz, dx, dy, dz, margin):
    """Where along the line ``o + t d`` (renderer frame, mm) the tools can matter: ``(low, high, keep_low,
    keep_high, removed_low, removed_high)``.

    - Outside ``[low, high]`` every tool's removal value is at least ``margin`` (tool units; give the largest ``g``
      that changes a sample: 0 for the binary test, ``width/2`` for the distance ramp, the cut band where cut normals
      are used), so a sample there is kept untouched without evaluating ``g``; ``low > high`` when the line misses
      every tool.
    - Outside ``[keep_low, keep_high]`` (the intersection over ``keep`` tools; the whole line when there is none)
      every sample is fully removed.
    - Inside ``[removed_low, removed_high]`` every sample is fully removed too: the longest chord of the line through
      a ``remove`` shape shrunk by the distance ramp's half width (a shape is convex, so its chord is all inside;
      ``removed_low > removed_high`` when there is none). Grid tools have no chord (their leap tables serve).

    Found in each tool's own frame, where the line stays a line: the shape grown by the margin (a sphere and a
    cylinder exactly, a box by its slabs, a half-space by its plane, a grid tool by its grid's box, outside which it
    removes nothing or, in ``keep`` mode, everything). With ``bounds`` off in the settings: the whole line, no chord.
    """
    kinds, modes, matrices, params, shapes, settings = tools[0], tools[1], tools[2], tools[3], tools[5], tools[7]
    low, high = np.inf, -np.inf
    keep_low, keep_high = -np.inf, np.inf
    removed_low, removed_high = 1.0, 0.0
    if settings[6] <= 0.0:
        return -np.inf, np.inf, keep_low, keep_high, removed_low, removed_high
    ramp = 0.0 if settings[0] == BINARY else 0.5 * settings[1]
    for t in range(kinds.shape[0]):
        ax, ay, az = to_tool(matrices, t, ox, oy, oz)
        bx = matrices[t, 0, 0] * dx + matrices[t, 0, 1] * dy + matrices[t, 0, 2] * dz
        by = matrices[t, 1, 0] * dx + matrices[t, 1, 1] * dy + matrices[t, 1, 2] * dz
        bz = matrices[t, 2, 0] * dx + matrices[t, 2, 1] * dy + matrices[t, 2, 2] * dz
        remove = modes[t] == REMOVE
        kind, p0, p1, p2 = kinds[t], params[t, 0], params[t, 1], params[t, 2]
        n0, n1, n2 = shapes[t, 0], shapes[t, 1], shapes[t, 2]
        t0, t1 = _shape_span(kind, p0, p1, p2, n0, n1, n2, ax, ay, az, bx, by, bz,
                             (margin if remove else ramp) + _BOUNDS_SLACK)
        if t0 <= t1:
            low = min(low, t0)
            high = max(high, t1)
        if not remove:
            keep_low = max(keep_low, t0)
            keep_high = min(keep_high, t1)
        elif kind != GRID:
            c0, c1 = _shape_span(kind, p0, p1, p2, n0, n1, n2, ax, ay, az, bx, by, bz, -ramp - _BOUNDS_SLACK)
            if c0 <= c1 and (removed_low > removed_high or c1 - c0 > removed_high - removed_low):
                removed_low, removed_high = c0, c1
    return low, high, keep_low, keep_high, removed_low, removed_high


@njit(cache=True, nogil=True)
def bounds_margin(tools, cut_normals):
    """The ``margin`` of :func:`ray_interval` for a renderer: the largest removal value that changes a sample (the
    distance ramp's half width, and the cut band when the renderer shades the cut with the tool's normal)."""
    settings = tools[7]
    margin = 0.0 if settings[0] == BINARY else 0.5 * settings[1]
    if cut_normals:
        margin = max(margin, settings[2])
    return margin


def reach_box(tools: tuple, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """The box (renderer frame, ``low``, ``high``; 3 each) outside which every tool of ``tools`` (packed, see
    :meth:`~algorithms.common.cutaway.ToolSet.packed`) has a removal value of at least ``margin``: a ray that
    stays outside it needs no :func:`ray_interval`. Unbounded (``-inf``, ``inf``) when some tool is a ``keep`` tool
    (outside it everything is removed), a half-space, or when bounds are off."""
    kinds, modes, matrices, params, shapes, settings = tools[0], tools[1], tools[2], tools[3], tools[5], tools[7]
    low, high = np.full(3, np.inf), np.full(3, -np.inf)
    unbounded = np.full(3, -np.inf), np.full(3, np.inf)
    if settings[6] <= 0.0:
        return unbounded
    for t in range(len(kinds)):
        if modes[t] != REMOVE or kinds[t] == HALFSPACE:
            return unbounded
        grow = margin + _BOUNDS_SLACK
        if kinds[t] == GRID:
            lo, hi = np.full(3, -_BOUNDS_SLACK), shapes[t].astype(np.float64) - 1.0 + _BOUNDS_SLACK
        elif kinds[t] == SPHERE:
            hi = np.full(3, params[t, 0] + grow)
            lo = -hi
        elif kinds[t] == CYLINDER:
            hi = np.array([params[t, 0], params[t, 0], params[t, 1]]) + grow
            lo = -hi
        else:  # BOX
            hi = np.asarray(params[t, :3], dtype=np.float64) + grow
            lo = -hi
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        try:
            inverse = np.linalg.inv(matrices[t])
        except np.linalg.LinAlgError:
            return unbounded
        points = corners @ inverse.T
        low = np.minimum(low, points[:, :3].min(axis=0))
        high = np.maximum(high, points[:, :3].max(axis=0))
    return low, high
