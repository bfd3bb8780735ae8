"""The body-centred cubic lattice of isosurface stuffing: its two grids, where it lies, and what it costs.

Source 002 (section 4.2.3) stores the lattice as two arrays, the outer grid ``(xDim, yDim, zDim)`` and the inner
grid one smaller per axis, of ``BccGridPoint`` records: position, sign and the cut parameters of three black and
four red half-edges, 44 bytes with alignment. It also names the compact variant for large lattices: a point keeps
only its sign and a reference to a record that exists where it is needed. That is what we store
(:mod:`.kernels`):

- per point, dense: the sign (int8), the reference to its record (int32, -1 for none) and its output vertex id
  (int32, -1 for none): 9 bytes;
- per point incident to a cut edge (a thin band about the surface): a record with its ``(grid, i, j, k)``, its
  (possibly warped) position, the cut parameters of its seven half-edges and the ids of their cut points:
  16 + 24 + 28 + 28 = 96 bytes.

:meth:`Lattice.bytes_per_point` reports the average against source 002's 44 bytes. Coordinates: ``(x, y, z)`` mm
in the volume frame; arrays ``[k, j, i]``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

#: Bytes per lattice point of source 002's ``BccGridPoint`` (41, aligned to 44).
SOURCE_BYTES_PER_POINT = 44
#: Our dense bytes per lattice point (sign, record reference, vertex id).
DENSE_BYTES_PER_POINT = 9
#: Bytes of one record (point index 4 x int32, position 3 x float64, 7 cut parameters float32, 7 cut ids int32).
RECORD_BYTES = 16 + 24 + 28 + 28


@dataclass(frozen=True)
class Lattice:
    """A BCC lattice of spacing ``h`` (mm): outer points at ``origin + h (i, j, k)``, ``0 <= i <= cells[0]``...,
    inner points at ``origin + h (i + 1/2, j + 1/2, k + 1/2)``, ``0 <= i < cells[0]``...

    ``cells`` is ``(NX, NY, NZ)``; the outer arrays have shape ``(NZ + 1, NY + 1, NX + 1)``, the inner ones
    ``(NZ, NY, NX)``.
    """

    origin: tuple[float, float, float]
    h: float
    cells: tuple[int, int, int]

    @property
    def outer_shape(self) -> tuple[int, int, int]:
        nx, ny, nz = self.cells
        return nz + 1, ny + 1, nx + 1

    @property
    def inner_shape(self) -> tuple[int, int, int]:
        nx, ny, nz = self.cells
        return nz, ny, nx

    @property
    def n_points(self) -> int:
        return int(np.prod(self.outer_shape)) + int(np.prod(self.inner_shape))

    @property
    def vector(self) -> np.ndarray:
        """``(x0, y0, z0, h)`` for the kernels."""
        return np.array([*self.origin, self.h], dtype=np.float64)

    def dense_bytes(self) -> int:
        return DENSE_BYTES_PER_POINT * self.n_points

    def bytes_per_point(self, records: int) -> float:
        """Average bytes per lattice point with ``records`` records, to compare with source 002's 44."""
        return (self.dense_bytes() + RECORD_BYTES * records) / max(self.n_points, 1)


def lattice_around(lower, upper, h: float) -> Lattice:
    """The lattice of spacing ``h`` whose outer points span ``[lower - h, upper + h]`` (mm, ``(x, y, z)``) or a
    little more: a layer of lattice points outside the box on every side, so points on the lattice's border lie
    outside the shape and the mesh is closed."""
    lower = np.asarray(lower, dtype=np.float64)
    upper = np.asarray(upper, dtype=np.float64)
    origin = lower - h
    cells = tuple(int(math.ceil((u - l) / h)) + 2 for l, u in zip(lower, upper))
    return Lattice(tuple(float(v) for v in origin), float(h), cells)


def physical_memory() -> int:
    """Bytes of memory of this machine (0 when unknown)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 0


def estimated_bytes(lattice: Lattice, inside_volume_mm3: float) -> int:
    """What a run will allocate, about: the dense lattice arrays, the output (tetrahedra: 12 per h^3 of the
    shape and up to 3 per boundary tetrahedron, int32 then int64; points: 2 per h^3, float64), and records for a
    band of points about the surface (bounded by the points of the shape's box)."""
    cells = inside_volume_mm3 / lattice.h ** 3
    tets = 14.0 * cells + 1000
    points = 2.5 * cells + 1000
    output = tets * (16 + 32) + points * 24 * 2
    return int(lattice.dense_bytes() + output)


def format_gib(count: float) -> str:
    return f"{count / 2**30:.1f} GiB"
