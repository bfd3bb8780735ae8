"""Marching cubes on one block of a larger volume, with vertices named by their global edge so blocks stitch exactly.

Method (source 001, "Techniek 1: Marching cubes", with Paul Bourke's tables; see :mod:`.core`): a volume too large
for memory is cut into blocks of cells; the block of cells ``[k0, k0 + cz) x [j0, j0 + cy) x [i0, i0 + cx)`` is
meshed from its samples plus a one-sample overlap on the high side (``cz + 1`` samples along k, ...), by the same
numba counting and filling passes as :func:`.core.marching_cubes` (:mod:`.kernels`). Each block makes exactly the
triangles of its own cells, so the blocks' triangles partition the whole mesh.

Global edge ids
---------------
Every vertex gets a key naming where it lies in the *whole* volume of shape ``(nz, ny, nx)``:

- a vertex strictly inside the edge from sample ``(k, j, i)`` along axis ``a`` (0, 1, 2 for x, y, z):
  ``4 * ((k * ny + j) * nx + i) + a``;
- a vertex exactly on sample ``(k, j, i)`` (``value == isovalue`` there): ``4 * ((k * ny + j) * nx + i) + 3``,
  shared by every cut edge meeting at that sample (as :func:`.core.marching_cubes` merges them).

Positions are computed from the global sample index with the same floating-point operations as the in-memory
kernels (``origin + spacing * (i + t)`` in float64, stored as float32, ``t = (iso - v0) / (v1 - v0)`` from the
edge's lower end), so a vertex on a face shared by two blocks has the same key and bit-identical coordinates in
both, and the stitched mesh (vertices merged by key, triangles collapsed by merging dropped) equals the in-memory
mesh: same triangles, same shared vertices. Normals are not computed here (they need two samples of overlap).

Array orders: blocks are ``(nz, ny, nx)`` indexed ``[k, j, i]``; ``start`` and ``volume_shape`` are in that order;
spacing and origin are ``(x, y, z)`` mm; points are ``(x, y, z)`` in the volume frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ...common.validation import validated_levels, validated_numeric_volume, validated_origin, validated_spacing
from . import kernels
from .core import _count, _inside_threshold, _numba_threads

__all__ = ["BlockMesh", "edge_keys_shape_limit", "marching_cubes_block"]


@dataclass(frozen=True)
class BlockMesh:
    """Marching cubes' triangles of one block: ``points`` (n, 3) float32 mm in the volume frame, ``keys`` (n,) int64
    global vertex keys (sorted, unique), ``triangles`` (m, 3) int64 indices into ``points``, counter-clockwise
    seen from outside."""

    points: np.ndarray
    keys: np.ndarray
    triangles: np.ndarray

    @classmethod
    def empty(cls) -> "BlockMesh":
        return cls(np.empty((0, 3), np.float32), np.empty(0, np.int64), np.empty((0, 3), np.int64))


def edge_keys_shape_limit(volume_shape) -> bool:
    """Whether the keys of a volume of this shape fit in int64 (4 keys per sample)."""
    return 4 * int(np.prod([int(n) for n in volume_shape], dtype=object)) < 2**63


def _cut_edges(inside: np.ndarray, ny: int, nx: int):
    """Lower-end sample ``(k, j, i)`` and axis of every cut edge, in the order the kernels number vertices:
    by edge row ``(k, j, axis)``, then ``i``."""
    parts = []
    for axis, (low, high) in enumerate((
            (inside[:, :, :-1], inside[:, :, 1:]), (inside[:, :-1, :], inside[:, 1:, :]),
            (inside[:-1], inside[1:]))):
        k, j, i = np.nonzero(low != high)
        parts.append((k, j, i, np.full(k.shape, axis, np.int64)))
    k, j, i, axis = (np.concatenate(column) for column in zip(*parts))
    order = np.argsort(((k * ny + j) * 3 + axis) * nx + i, kind="stable")
    return k[order], j[order], i[order], axis[order]


def marching_cubes_block(block, level, *, start, volume_shape, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0),
                         threads: int | None = None) -> BlockMesh:
    """The marching-cubes triangles of the cells of one block, with global vertex keys.

    Parameters
    ----------
    block : ndarray, shape (bz, by, bx)
        Samples ``[k0 : k0 + bz, j0 : j0 + by, i0 : i0 + bx]`` of the whole volume: the block's cells plus one
        sample of overlap with the next block on each axis (none at the volume's far end). At least 2 per axis.
    level : float
        One isovalue; inside is ``value >= level``.
    start : (k0, j0, i0)
        Index of the block's first sample in the whole volume.
    volume_shape : (nz, ny, nx)
        Shape of the whole volume (for the keys).
    spacing, origin : (x, y, z) mm
        Of the whole volume: sample ``(i, j, k)`` lies at ``origin + spacing * (i, j, k)``.
    threads : int, optional
        numba threads for this block (default: numba's setting; 1 inside a Dask task that has its own workers).

    Returns
    -------
    BlockMesh

    Raises
    ------
    ValueError
        Bad block (not 3D, fewer than 2 samples per axis, NaN), isovalue, geometry, or a block that does not lie
        inside ``volume_shape``.
    """
    array = validated_numeric_volume(block, min_size=2)
    levels = validated_levels(level)
    if levels.size != 1:
        raise ValueError("marching_cubes_block takes one isovalue")
    iso = float(levels[0])
    spacing = validated_spacing(spacing)
    origin = validated_origin(origin)
    start = tuple(int(s) for s in start)
    volume_shape = tuple(int(n) for n in volume_shape)
    if len(start) != 3 or len(volume_shape) != 3:
        raise ValueError(f"start and volume_shape need three entries (k, j, i), got {start} and {volume_shape}")
    if min(start) < 0 or any(s + b > n for s, b, n in zip(start, array.shape, volume_shape)):
        raise ValueError(f"a block of shape {array.shape} at {start} does not lie inside a volume of shape "
                         f"{volume_shape}")
    if not edge_keys_shape_limit(volume_shape):
        raise ValueError(f"a volume of shape {volume_shape} has too many samples for 64-bit vertex keys")
    threshold = _inside_threshold(array.dtype, iso)
    if threshold is None:
        return BlockMesh.empty()
    threads = numba.get_num_threads() if threads is None else max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
    with _numba_threads(threads):
        counts = _count(array, threshold, None)
        if counts.triangle_total == 0:
            return BlockMesh.empty()
        vertex_first = np.cumsum(counts.edges.ravel()).reshape(counts.edges.shape)
        vertex_total = int(vertex_first[-1, -1, -1])
        vertex_first -= counts.edges
        triangle_first = np.cumsum(counts.triangles.ravel()).reshape(counts.triangles.shape)
        triangle_first -= counts.triangles
        # The kernels' own positions (local frame) and sample flags are not used: the keys and global positions
        # are computed below from the same edges, numbered in the same order.
        scratch = np.empty((vertex_total, 3), dtype=np.float32)
        on_sample = np.empty(vertex_total, dtype=np.int64)
        triangles = np.empty((counts.triangle_total, 3), dtype=np.int64)
        layers = np.arange(array.shape[0], dtype=np.int64)  # one layer of cells per work item
        kernels.fill_layers(array, threshold, iso, layers, numba.get_num_threads(), counts.spans, vertex_first,
                            triangle_first, kernels.PAIR_CASE, kernels.TRIANGLES, kernels.TRIANGLE_COUNT, spacing,
                            np.zeros(3), scratch, np.empty((0, 3), np.float32), on_sample, triangles)
    del scratch, on_sample, counts, vertex_first, triangle_first
    _, ny, nx = array.shape
    k, j, i, axis = _cut_edges(array >= threshold, ny, nx)
    if k.shape[0] != vertex_total:  # the kernels and this numbering disagree: never silently wrong
        raise RuntimeError(f"marching cubes numbered {vertex_total} vertices but the block has {k.shape[0]} cut edges")
    v0 = array[k, j, i].astype(np.float64)
    v1 = array[k + (axis == 2), j + (axis == 1), i + (axis == 0)].astype(np.float64)
    t = (iso - v0) / (v1 - v0)
    gk, gj, gi = k + start[0], j + start[1], i + start[2]
    points = np.empty((k.shape[0], 3), dtype=np.float32)
    for column, (index, along) in enumerate(((gi, 0), (gj, 1), (gk, 2))):
        position = index.astype(np.float64)
        position = np.where(axis == along, position + t, position)
        points[:, column] = origin[column] + spacing[column] * position
    _, vy, vx = volume_shape
    flat = (gk * vy + gj) * vx + gi
    step = np.where(axis == 0, 1, np.where(axis == 1, vx, vy * vx))
    keys = np.where(t == 0.0, 4 * flat + 3, np.where(t == 1.0, 4 * (flat + step) + 3, 4 * flat + axis))
    unique, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    triangles = inverse[triangles]
    kept = (triangles[:, 0] != triangles[:, 1]) & (triangles[:, 1] != triangles[:, 2]) & (
        triangles[:, 0] != triangles[:, 2])
    return BlockMesh(points[first], unique.astype(np.int64), np.ascontiguousarray(triangles[kept]))
