"""Exact geometric predicates for the row tests of mesh voxelisation (numba, scalar).

:func:`orient2d_sign` is the sign of the 2D orientation determinant, exact for any double-precision input: a
floating-point filter decides almost every call, and only when the rounded value is too close to zero to be
trusted is the determinant evaluated exactly as a floating-point expansion (a sum of non-overlapping doubles).
:func:`edge_side` adds simulation of simplicity: a point lying exactly on an edge's line is moved off it by an
infinitesimal ``(e, e^2)``, so the answer is never zero.

This is the same convention as :func:`algorithms.compare.topology.ray_crossings` (rays towards +x from points
perturbed by ``(0, e, e^2)``, each edge judged from its lower to its higher vertex index), made exact and compiled
for use inside the voxelisation kernels: there the sign must be exact, not just consistent, because a row through
a vertex is decided once per triangle of the vertex's fan and all of those decisions must describe one perturbed
point.

References
----------
J. R. Shewchuk, "Adaptive precision floating-point arithmetic and fast robust geometric predicates", Discrete &
Computational Geometry 18(3), 305-363, 1997. doi:10.1007/PL00009321.
H. Edelsbrunner, E. P. Mücke, "Simulation of simplicity: a technique to cope with degenerate cases in geometric
algorithms", ACM Transactions on Graphics 9(1), 66-104, 1990. doi:10.1145/77635.77639.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_EPSILON = 2.0 ** -53
_SPLITTER = 2.0 ** 27 + 1.0
#: Shewchuk's bound for the first, plain floating-point evaluation of orient2d.
_CCW_ERRBOUND_A = (3.0 + 16.0 * _EPSILON) * _EPSILON


@njit(cache=True, forceinline=True)
def _two_sum(a, b):
    x = a + b
    b_virtual = x - a
    a_virtual = x - b_virtual
    return x, (a - a_virtual) + (b - b_virtual)


@njit(cache=True, forceinline=True)
def _two_diff(a, b):
    x = a - b
    b_virtual = a - x
    a_virtual = x + b_virtual
    return x, (a - a_virtual) + (b_virtual - b)


@njit(cache=True, forceinline=True)
def _split(a):
    c = _SPLITTER * a
    big = c - a
    high = c - big
    return high, a - high


@njit(cache=True, forceinline=True)
def _two_product(a, b):
    x = a * b
    a_high, a_low = _split(a)
    b_high, b_low = _split(b)
    error = x - a_high * b_high
    error -= a_low * b_high
    error -= a_high * b_low
    return x, a_low * b_low - error


@njit(cache=True)
def _grow(expansion, length, value):
    """Add ``value`` to the non-overlapping expansion ``expansion[:length]`` (Shewchuk's Grow-Expansion with zero
    elimination), in place; returns the new length."""
    q = value
    out = 0
    for index in range(length):
        q, h = _two_sum(q, expansion[index])
        if h != 0.0:
            expansion[out] = h
            out += 1
    if q != 0.0:
        expansion[out] = q
        out += 1
    return out


@njit(cache=True, forceinline=False)  # rarely taken: stated, not inherited (common.cutaway, compile time)
def _orient2d_exact_sign(ax, ay, bx, by, cx, cy):
    """Exact sign of ``(a - c) x (b - c)``: every difference and product split into exact double pairs and summed
    as an expansion, whose largest component carries the sign."""
    acx, acx_tail = _two_diff(ax, cx)
    acy, acy_tail = _two_diff(ay, cy)
    bcx, bcx_tail = _two_diff(bx, cx)
    bcy, bcy_tail = _two_diff(by, cy)
    expansion = np.empty(40, dtype=np.float64)
    length = np.int64(0)  # not a literal 0: numba would compile _grow for it as well as for int64
    left = (acx, acx_tail)
    right = (bcy, bcy_tail)
    for u in left:
        for v in right:
            high, low = _two_product(u, v)
            length = _grow(expansion, length, low)
            length = _grow(expansion, length, high)
    left = (acy, acy_tail)
    right = (bcx, bcx_tail)
    for u in left:
        for v in right:
            high, low = _two_product(u, v)
            length = _grow(expansion, length, -low)
            length = _grow(expansion, length, -high)
    if length == 0:
        return 0
    return 1 if expansion[length - 1] > 0.0 else -1


@njit(cache=True, forceinline=True)
def orient2d_sign(ax, ay, bx, by, cx, cy):
    """Exact sign (-1, 0, +1) of ``(a - c) x (b - c)``, twice the signed area of the triangle ``a, b, c``.

    Positive when ``a, b, c`` turn counter-clockwise. Also returns the rounded determinant (for interpolation
    weights; its sign may differ from the exact one only when it is within rounding of zero).
    """
    left = (ax - cx) * (by - cy)
    right = (ay - cy) * (bx - cx)
    det = left - right
    if left > 0.0:
        if right <= 0.0:
            return (1 if det > 0.0 else (-1 if det < 0.0 else 0)), det
        total = left + right
    elif left < 0.0:
        if right >= 0.0:
            return (1 if det > 0.0 else (-1 if det < 0.0 else 0)), det
        total = -left - right
    else:
        return (1 if det > 0.0 else (-1 if det < 0.0 else 0)), det
    if det >= _CCW_ERRBOUND_A * total or -det >= _CCW_ERRBOUND_A * total:
        return (1 if det > 0.0 else -1), det
    return _orient2d_exact_sign(ax, ay, bx, by, cx, cy), det


@njit(cache=True, forceinline=True)
def edge_side(uy, uz, vy, vz, y, z):
    """Side (+1 or -1) of the point ``(y + e, z + e^2)`` relative to the directed edge ``u -> v`` in the (y, z)
    plane, and the rounded determinant ``(v - u) x (p - u)``.

    +1 means the point lies to the left of the edge (counter-clockwise). The exact determinant decides; when it is
    zero the perturbation does: ``det(e) = det - dz e + dy e^2``. Zero is returned only for an edge seen end-on
    (``u`` and ``v`` project to the same point), which no point can be on either side of.
    """
    sign, det = orient2d_sign(uy, uz, vy, vz, y, z)
    if sign != 0:
        return sign, det
    dz = vz - uz
    if dz != 0.0:
        return (1 if dz < 0.0 else -1), det
    dy = vy - uy
    if dy != 0.0:
        return (1 if dy > 0.0 else -1), det
    return 0, det
