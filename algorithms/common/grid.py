"""A regular grid in patient space: dimensions, spacing, origin and direction, as volumes and fields have them.

Axis order: ``dimensions`` is ``(nx, ny, nz)`` (VTK order) and :attr:`Grid.shape` the matching NumPy shape
``(nz, ny, nx)``; spacing and origin are ``(x, y, z)`` in mm; ``direction`` is 3x3 with the unit LPS directions of
the i, j, k axes as columns. The world position of voxel ``(i, j, k)`` (its centre) is
``origin + direction @ (spacing * (i, j, k))``. Mesh voxelisation, distance fields, CSG and cut-away tools all take
a grid, so anisotropic spacing and rotated grids work everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

MAX_GRID_VOXELS = 2**31 - 1  # voxel indices must fit the int32 arithmetic of the kernels


def _triple(values, name: str, *, positive: bool = False, integer: bool = False) -> tuple:
    try:
        items = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers (x, y, z), got {values!r}") from None
    if len(items) != 3 or not all(math.isfinite(v) for v in items):
        raise ValueError(f"{name} must be three finite numbers (x, y, z), got {values!r}")
    if positive and min(items) <= 0:
        raise ValueError(f"{name} must be positive, got {values!r}")
    if integer:
        if any(v != int(v) for v in items):
            raise ValueError(f"{name} must be whole numbers, got {values!r}")
        return tuple(int(v) for v in items)
    return items


@dataclass(frozen=True)
class Grid:
    """A regular grid of voxel centres. Validated on construction (ValueError with what is wrong)."""

    dimensions: tuple[int, int, int]
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        dimensions = _triple(self.dimensions, "grid dimensions", positive=True, integer=True)
        if math.prod(dimensions) > MAX_GRID_VOXELS:
            raise ValueError(f"a grid of {' x '.join(map(str, dimensions))} voxels is too large "
                             f"(at most {MAX_GRID_VOXELS:,} voxels)")
        object.__setattr__(self, "dimensions", dimensions)
        object.__setattr__(self, "spacing", _triple(self.spacing, "grid spacing (mm)", positive=True))
        object.__setattr__(self, "origin", _triple(self.origin, "grid origin (mm)"))
        matrix = np.asarray(self.direction, dtype=np.float64).reshape(-1)
        if matrix.size != 9 or not np.all(np.isfinite(matrix)):
            raise ValueError("the grid direction must be a finite 3x3 matrix")
        matrix = matrix.reshape(3, 3)
        if not np.allclose(matrix.T @ matrix, np.eye(3), atol=1e-4):
            raise ValueError(f"the grid direction must be orthonormal, got {matrix.tolist()}")
        object.__setattr__(self, "direction", tuple(float(v) for v in matrix.ravel()))

    # -- shapes and matrices ----------------------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int, int]:
        """NumPy shape ``(nz, ny, nx)`` of an array on this grid."""
        nx, ny, nz = self.dimensions
        return nz, ny, nx

    @property
    def size(self) -> int:
        return int(math.prod(self.dimensions))

    @property
    def direction_matrix(self) -> np.ndarray:
        return np.asarray(self.direction, dtype=np.float64).reshape(3, 3)

    @property
    def voxel_volume(self) -> float:
        """mm^3 of one voxel."""
        return float(math.prod(self.spacing))

    @property
    def affine(self) -> np.ndarray:
        """4x4 matrix taking homogeneous index ``(i, j, k, 1)`` to LPS mm."""
        matrix = np.eye(4)
        matrix[:3, :3] = self.direction_matrix * np.asarray(self.spacing)[None, :]
        matrix[:3, 3] = self.origin
        return matrix

    @property
    def local_to_world(self) -> np.ndarray:
        """4x4 rigid matrix taking the grid's own frame (index times spacing, mm) to LPS mm."""
        matrix = np.eye(4)
        matrix[:3, :3] = self.direction_matrix
        matrix[:3, 3] = self.origin
        return matrix

    def index_to_world(self, ijk) -> np.ndarray:
        """LPS mm of index coordinates ``(..., 3)`` given as ``(i, j, k)``."""
        ijk = np.asarray(ijk, dtype=np.float64)
        return ijk * np.asarray(self.spacing) @ self.direction_matrix.T + np.asarray(self.origin)

    def world_to_index(self, points) -> np.ndarray:
        """Continuous ``(i, j, k)`` of LPS points ``(..., 3)``."""
        points = np.asarray(points, dtype=np.float64) - np.asarray(self.origin)
        return points @ self.direction_matrix / np.asarray(self.spacing)

    @property
    def world_bounds(self) -> tuple[float, float, float, float, float, float]:
        """Axis-aligned LPS bounds of the voxel centres ``(xmin, xmax, ymin, ymax, zmin, zmax)``."""
        nx, ny, nz = self.dimensions
        corners = np.array([[i, j, k] for k in (0, nz - 1) for j in (0, ny - 1) for i in (0, nx - 1)], float)
        world = self.index_to_world(corners)
        low, high = world.min(axis=0), world.max(axis=0)
        return (float(low[0]), float(high[0]), float(low[1]), float(high[1]), float(low[2]), float(high[2]))

    def same_as(self, other: "Grid", *, tolerance: float = 1e-6) -> bool:
        """Same dimensions and, within ``tolerance`` (mm), the same voxel centres."""
        return (self.dimensions == other.dimensions
                and np.allclose(self.spacing, other.spacing, atol=tolerance)
                and np.allclose(self.origin, other.origin, atol=tolerance)
                and np.allclose(self.direction, other.direction, atol=tolerance))

    def describe(self) -> dict:
        return {"dimensions": list(self.dimensions), "spacing": list(self.spacing), "origin": list(self.origin),
                "direction": list(self.direction)}

    # -- grids around things ------------------------------------------------------------------------------------------
    @classmethod
    def around(cls, bounds: Sequence[float], *, voxels: int | None = None, spacing=None,
               padding: int = 2) -> "Grid":
        """An axis-aligned grid (identity direction) around ``bounds`` ``(xmin, xmax, ymin, ymax, zmin, zmax)``.

        Either ``voxels`` cubic voxels along the longest side of the bounds, or the given ``spacing`` (mm, three
        values or one); then ``padding`` voxels of margin on every side.
        """
        low = np.asarray(bounds[0::2], dtype=np.float64)
        high = np.asarray(bounds[1::2], dtype=np.float64)
        if low.shape != (3,) or not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))) or np.any(high < low):
            raise ValueError(f"bounds must be finite (xmin, xmax, ymin, ymax, zmin, zmax), got {list(bounds)}")
        if int(padding) != padding or padding < 0:
            raise ValueError(f"padding is a whole number of voxels, 0 or more; got {padding}")
        extent = high - low
        if (voxels is None) == (spacing is None):
            raise ValueError("give either the number of voxels along the longest side or the spacing, not both")
        if voxels is not None:
            if int(voxels) != voxels or voxels < 2:
                raise ValueError(f"the grid needs at least 2 voxels along its longest side, got {voxels}")
            if extent.max() <= 0:
                raise ValueError("the object has no extent: its bounds are a single point")
            step = np.full(3, extent.max() / (int(voxels) - 1))
        else:
            step = np.broadcast_to(np.asarray(spacing, dtype=np.float64).reshape(-1), (3,)).copy()
            if not np.all(np.isfinite(step)) or step.min() <= 0:
                raise ValueError(f"the spacing must be positive millimetres, got {spacing!r}")
        counts = np.maximum(np.ceil(extent / step - 1e-9).astype(np.int64) + 1, 1)
        centre = (low + high) / 2
        origin = centre - step * (counts - 1) / 2 - step * padding
        dimensions = tuple(int(n + 2 * padding) for n in counts)
        return cls(dimensions, tuple(step), tuple(origin))
