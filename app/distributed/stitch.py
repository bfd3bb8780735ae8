"""Stitching per-block marching-cubes pieces into one indexed mesh by their global vertex keys.

Each piece (:class:`algorithms.surfaces.marching_cubes.blocks.BlockMesh`) names its vertices by global edge (or
sample) keys; a vertex on a face shared by two blocks has the same key, and bit-identical coordinates, in both.
:class:`Stitcher` keeps the pieces as they arrive (the client holds the mesh, never samples) and merges them once:
one vertex per key, triangles renumbered. No tolerance is involved: stitching is exact.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Stitcher"]


class Stitcher:
    """Collects pieces ``(points (n, 3) float32, keys (n,) int64, triangles (m, 3) int64)`` and merges them."""

    def __init__(self) -> None:
        self._points: list[np.ndarray] = []
        self._keys: list[np.ndarray] = []
        self._triangles: list[np.ndarray] = []
        self.pieces = 0

    def add(self, piece) -> None:
        """Add one block's mesh (empty pieces are counted and dropped)."""
        self.pieces += 1
        if piece.triangles.shape[0] == 0:
            return
        self._points.append(piece.points)
        self._keys.append(piece.keys)
        self._triangles.append(piece.triangles)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for group in (self._points, self._keys, self._triangles) for a in group)

    def merged(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points ``(n, 3)`` float32, their keys (sorted), and triangles ``(m, 3)`` int64 of the whole mesh.

        Frees the pieces as it goes. Raises ``ValueError`` when two pieces give one key different coordinates
        (the blocks were not cut from one volume with one geometry).
        """
        if not self._keys:
            return np.empty((0, 3), np.float32), np.empty(0, np.int64), np.empty((0, 3), np.int64)
        offsets = np.cumsum([0] + [k.shape[0] for k in self._keys])
        keys = np.concatenate(self._keys)
        self._keys.clear()
        points = np.concatenate(self._points)
        self._points.clear()
        unique, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        if not np.array_equal(points, points[first][inverse]):
            raise ValueError("two blocks placed one vertex differently; the pieces do not come from one volume")
        triangles = np.concatenate([t + offset for t, offset in zip(self._triangles, offsets[:-1])])
        self._triangles.clear()
        return points[first], unique, inverse[triangles]
