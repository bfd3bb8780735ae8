"""The shear-warp renderer's data structures: quantised normals and the classified volume per principal axis,
run-length encoded (source 004, sections 5.2.2 and 5.2.7) or dense (the brute-force ablation).

See :mod:`algorithms.rendering.shear_warp` for the method and :mod:`.kernels` for the array layouts.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from . import kernels
from .factorisation import standard_order

#: Longest scanline a uint16 run length can describe.
MAX_SCANLINE = 65535
#: Largest normal grid whose indices (about 2 pi (grid / 2)^2 of them) fit in uint16.
MAX_NORMAL_GRID = 200


def checked_grid(grid) -> int:
    whole = isinstance(grid, (int, np.integer)) and not isinstance(grid, bool)
    if not whole or grid % 2 or not 2 <= grid <= MAX_NORMAL_GRID:
        raise ValueError(f"normal_grid must be an even integer from 2 to {MAX_NORMAL_GRID}, got {grid!r}")
    return int(grid)


@dataclass(frozen=True)
class NormalTable:
    """Unit normals on the source's grid (section 5.2.7), with the encoding table and per-view shade maps.

    A grid of ``grid x grid`` cells with centre ``C = grid / 2``, one grid per hemisphere (``nz >= 0`` and
    ``nz < 0``). A unit normal is encoded by the vertex ``(vx, vy) = (rint(C + C nx), rint(C + C ny))`` and its
    hemisphere; the encoding table gives the vertex's index. Only vertices whose cell reaches the unit disc are used
    (the "shaded cells" of the source's figure 21). The decoding table holds, per vertex, the normalised mean of the
    directions of its cell: the source's ``((vx - C) / C, (vy - C) / C, sqrt(1 - nx^2 - ny^2))`` for cells inside
    the disc, but for cells on its rim a direction near the equator, where the source's vertex normal would tilt
    equatorial normals by up to ``sqrt(2 / C)`` radians towards the pole. The projection stays sparse near the
    equator: with ``grid = 128`` the mean error is 0.8 degrees and the 99th percentile 4.6 degrees. The last index
    is the zero normal of homogeneous regions.

    Attributes
    ----------
    grid : int
        Cells per side (even).
    normals : ndarray (n + 1, 3) float64
        Decoding table: the unit normal of each index (x, y, z in the volume frame); the last row is zero.
    encoding : ndarray (2, grid + 1, grid + 1) int32
        Encoding table: index of vertex ``(vx, vy)`` in hemisphere 0 (``nz >= 0``) or 1; -1 for unused vertices.
    """

    grid: int
    normals: np.ndarray
    encoding: np.ndarray

    @classmethod
    def build(cls, grid: int) -> "NormalTable":
        """The table for a ``grid``-cell grid (even, 2 to :data:`MAX_NORMAL_GRID`)."""
        grid = checked_grid(grid)
        centre = grid // 2
        offset = np.arange(grid + 1, dtype=np.float64) - centre
        dx, dy = np.meshgrid(offset, offset, indexing="ij")
        # A vertex is used when its cell [v - 1/2, v + 1/2]^2 reaches the disc of radius C.
        gap_x, gap_y = np.maximum(np.abs(dx) - 0.5, 0.0), np.maximum(np.abs(dy) - 0.5, 0.0)
        used = gap_x**2 + gap_y**2 <= centre**2
        # Mean direction over each cell, from 8 x 8 samples (the cell's part inside the disc).
        sub = (np.arange(8) + 0.5) / 8 - 0.5
        mean = np.zeros(dx.shape + (3,))
        for su, sv in itertools.product(sub, sub):
            nx, ny = (dx + su) / centre, (dy + sv) / centre
            inside = nx * nx + ny * ny <= 1.0
            nz = np.sqrt(np.clip(1.0 - nx * nx - ny * ny, 0.0, None))
            mean += np.where(inside[..., None], np.stack([nx, ny, nz], axis=-1), 0.0)
        rim_only = used & ~np.any(mean != 0.0, axis=-1)  # a cell that only touches the disc: equatorial
        mean[rim_only] = np.stack([dx, dy, np.zeros_like(dx)], axis=-1)[rim_only]
        upper = mean[used] / np.linalg.norm(mean[used], axis=1, keepdims=True)
        count = len(upper)
        index = np.full(dx.shape, -1, dtype=np.int32)
        index[used] = np.arange(count, dtype=np.int32)
        encoding = np.stack([index, np.where(used, index + count, -1)]).astype(np.int32)
        normals = np.vstack([upper, upper * np.array([1.0, 1.0, -1.0]), np.zeros((1, 3))])
        normals.setflags(write=False)
        encoding.setflags(write=False)
        return cls(grid, normals, encoding)

    @property
    def zero_index(self) -> int:
        """Index of the zero normal (no gradient)."""
        return len(self.normals) - 1

    def encode(self, vectors: np.ndarray) -> np.ndarray:
        """Indices of the directions ``vectors`` ``(..., 3)`` (normalised here; zero vectors get :attr:`zero_index`)."""
        vectors = np.asarray(vectors, dtype=np.float64)
        norm = np.linalg.norm(vectors, axis=-1)
        unit = vectors / np.where(norm > 0, norm, 1.0)[..., None]
        centre = self.grid // 2
        vx = np.rint(centre + centre * unit[..., 0]).astype(np.int64)
        vy = np.rint(centre + centre * unit[..., 1]).astype(np.int64)
        hemisphere = (unit[..., 2] < 0).astype(np.int64)
        return np.where(norm > 0, self.encoding[hemisphere, vx, vy], self.zero_index)

    def shade(self, light: np.ndarray, viewer: np.ndarray, *, ambient: float, diffuse: float, specular: float,
              specular_power: float) -> np.ndarray:
        """Per-view shade map ``(n + 1, 2)`` float32: Blinn-Phong diffuse factor and specular term per normal.

        A voxel of colour ``c`` and normal ``n`` is shaded ``c * (ambient + diffuse |n.l|) + specular |n.h|^p``
        with ``h = normalize(l + e)`` (``l`` towards the light, ``e`` towards the viewer, both unit); lighting is
        two-sided (absolute cosines) as in VTK's renderers by default. The zero normal gets the ambient term only.
        """
        light = np.asarray(light, dtype=np.float64) / np.linalg.norm(light)
        halfway = light + np.asarray(viewer, dtype=np.float64) / np.linalg.norm(viewer)
        halfway = halfway / np.linalg.norm(halfway) if np.linalg.norm(halfway) > 0 else light
        table = np.empty((len(self.normals), 2), dtype=np.float32)
        table[:, 0] = ambient + diffuse * np.abs(self.normals @ light)
        table[:, 1] = specular * np.abs(self.normals @ halfway) ** specular_power
        table[-1] = (ambient, 0.0)
        return table


@dataclass(frozen=True)
class RunLengthVolume:
    """One run-length encoded copy of the classified volume, for one principal axis (source 004, 5.2.2).

    Attributes
    ----------
    principal_axis : int
        0, 1, 2 = x, y, z: the axis whose slices this copy stores (see :func:`standard_order`).
    shape : (nk, nj, ni)
        Standard-order shape: slices, scanlines per slice, voxels per scanline.
    run_lengths : ndarray uint16
        Per scanline, alternating transparent / non-transparent run lengths starting with a transparent run
        (possibly of length 0) and adding up to ``ni``; one sentinel run ends the array.
    classes : ndarray uint16
        Transfer-function entry of every non-transparent voxel, scanline after scanline.
    normals : ndarray uint16
        Normal index of every non-transparent voxel (empty without shading).
    line_runs, line_voxels : ndarray int64 (nk * nj)
        First run and first stored voxel of scanline ``(k, j)`` at ``k * nj + j``.
    """

    principal_axis: int
    shape: tuple[int, int, int]
    run_lengths: np.ndarray
    classes: np.ndarray
    normals: np.ndarray
    line_runs: np.ndarray
    line_voxels: np.ndarray

    @property
    def slice_runs(self) -> np.ndarray:
        """The source's per-slice pointer into :attr:`run_lengths` (first run of each slice), ``(nk,)``."""
        return self.line_runs[:: self.shape[1]]

    @property
    def slice_voxels(self) -> np.ndarray:
        """The source's per-slice pointer into :attr:`classes` (first stored voxel of each slice), ``(nk,)``."""
        return self.line_voxels[:: self.shape[1]]

    @property
    def nbytes(self) -> int:
        """Bytes of the runs, the stored voxels and the scanline pointers."""
        arrays = (self.run_lengths, self.classes, self.normals, self.line_runs, self.line_voxels)
        return int(sum(a.nbytes for a in arrays))

    @property
    def stored_voxels(self) -> int:
        return int(len(self.classes))

    def decode(self, fill: int) -> np.ndarray:
        """The dense standard-order class array ``(nk, nj, ni)`` uint16, ``fill`` at transparent voxels."""
        nk, nj, ni = self.shape
        return kernels.decode_runs(self.run_lengths, self.classes, self.line_runs, self.line_voxels, nk, nj, ni,
                                   np.uint16(fill))


def run_length_encode(classes: np.ndarray, visible: np.ndarray, *, normals: np.ndarray | None = None,
                      principal_axis: int = 2) -> RunLengthVolume:
    """Run-length encode a classified volume given in standard order (source 004, section 5.2.2).

    Parameters
    ----------
    classes : ndarray (nk, nj, ni), uint16
        Transfer-function entry of every voxel, in standard order (:func:`standard_order`).
    visible : ndarray (n_entries,), bool
        Whether a transfer-function entry is non-transparent.
    normals : ndarray (nk, nj, ni), uint16, optional
        Normal index of every voxel; stored for the non-transparent ones.
    principal_axis : int
        Recorded in the result.

    Returns
    -------
    RunLengthVolume
    """
    classes = np.ascontiguousarray(classes, dtype=np.uint16)
    if classes.ndim != 3 or min(classes.shape) < 1:
        raise ValueError(f"classes must be a non-empty (nk, nj, ni) array, got shape {classes.shape}")
    nk, nj, ni = classes.shape
    if ni > MAX_SCANLINE:
        raise ValueError(f"scanlines longer than {MAX_SCANLINE} voxels cannot be run-length encoded (got {ni})")
    visible = np.ascontiguousarray(visible, dtype=np.bool_)
    if visible.ndim != 1 or int(classes.max()) >= len(visible):
        raise ValueError("visible must be a 1D flag per transfer-function entry covering every class")
    if normals is None:
        normals = np.empty((0, 0, 0), dtype=np.uint16)
    else:
        normals = np.ascontiguousarray(normals, dtype=np.uint16)
        if normals.shape != classes.shape:
            raise ValueError(f"normals shape {normals.shape} differs from classes shape {classes.shape}")
    run_counts, voxel_counts = kernels.count_runs(classes, visible)
    line_runs = np.zeros(nk * nj, dtype=np.int64)
    line_voxels = np.zeros(nk * nj, dtype=np.int64)
    np.cumsum(run_counts[:-1], out=line_runs[1:])
    np.cumsum(voxel_counts[:-1], out=line_voxels[1:])
    total_runs = int(run_counts.sum())
    total_voxels = int(voxel_counts.sum())
    run_lengths = np.empty(total_runs + 1, dtype=np.uint16)
    run_lengths[-1] = kernels.SENTINEL_RUN
    voxel_classes = np.empty(total_voxels, dtype=np.uint16)
    voxel_normals = np.empty(total_voxels if normals.size else 0, dtype=np.uint16)
    kernels.fill_runs(classes, normals, visible, line_runs, line_voxels, run_lengths, voxel_classes, voxel_normals)
    return RunLengthVolume(int(principal_axis), (nk, nj, ni), run_lengths, voxel_classes, voxel_normals, line_runs,
                           line_voxels)


@dataclass(frozen=True)
class DenseVolume:
    """The brute-force counterpart of :class:`RunLengthVolume`: every voxel's class (and normal), standard order.

    Transparent voxels hold the index of the all-zero row that follows the transfer function's entries.
    """

    classes: np.ndarray
    normals: np.ndarray

    @property
    def nbytes(self) -> int:
        return int(self.classes.nbytes + self.normals.nbytes)


def standard_copy(array: np.ndarray, principal_axis: int) -> np.ndarray:
    """A C-contiguous standard-order copy (or the array itself when it already is in that order)."""
    view = standard_order(array, principal_axis)
    if view.flags.c_contiguous:
        return view
    out = np.empty(view.shape, dtype=view.dtype)
    kernels.copy_blocked(view, out)
    return out
