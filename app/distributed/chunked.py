"""Chunked marching cubes of a Zarr/OME-Zarr volume as Dask tasks, stitched exactly into the in-memory mesh.

Method: the volume's storage chunks are the blocks of cells; each task opens the store on its worker, reads its
chunk plus one sample of overlap on the high side of each axis, and runs
:func:`algorithms.surfaces.marching_cubes.blocks.marching_cubes_block` (our marching cubes, source 001, with Paul
Bourke's tables), which names every vertex by its global edge key. :class:`.stitch.Stitcher` merges the pieces by
key as they finish. A chunk is skipped without being read when it and the neighbours its overlap reaches lie on
one side of the isovalue, from the per-chunk ranges ``convert`` stores (``chunk_range``) or, for stores without
them, from a first pass of min/max tasks.

Only keys, points and triangles travel to the client; no sample does. Progress is the fraction of finished tasks;
a progress callback raising :class:`~algorithms.common.progress.OperationCancelled` cancels the futures.

Array orders: ``(nz, ny, nx)`` samples, chunk grid ``(cz, cy, cx)``; spacing and origin ``(x, y, z)`` mm; points
in the volume frame (mm, ``origin + spacing * (i, j, k)``), moved to LPS by the caller.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .stitch import Stitcher

__all__ = ["ChunkedMesh", "mesh_chunked", "plan_blocks"]


@dataclass
class ChunkedMesh:
    """The stitched mesh: ``points`` (n, 3) float32 in the volume frame (mm), ``triangles`` (m, 3) int64, and what
    the run did (``stats``: blocks, skipped, seconds, workers)."""

    points: np.ndarray
    triangles: np.ndarray
    stats: dict[str, Any] = field(default_factory=dict)


def _starts(shape, chunks):
    """First sample of every block along each axis (the storage chunk grid; the last sample has no cells)."""
    return [np.arange(0, max(n - 1, 1), c) for n, c in zip(shape, chunks)]


def plan_blocks(shape, chunks, iso: float, chunk_range: np.ndarray | None):
    """The blocks to mesh as ``(start, stop)`` sample ranges (stop exclusive, overlap included), and how many were
    skipped because the surface cannot cross them (``chunk_range`` (cz, cy, cx, 2) of min/max per chunk)."""
    starts = _starts(shape, chunks)
    grid = tuple(len(s) for s in starts)
    crossing = np.ones(grid, dtype=bool)
    if chunk_range is not None:
        lo, hi = chunk_range[..., 0], chunk_range[..., 1]
        below = np.pad(hi < iso, [(0, 1)] * 3, constant_values=True)  # beyond the far end: no samples
        above = np.pad(lo >= iso, [(0, 1)] * 3, constant_values=True)
        all_below = np.ones(grid, bool)
        all_above = np.ones(grid, bool)
        for dz in (0, 1):
            for dy in (0, 1):
                for dx in (0, 1):
                    all_below &= below[dz:dz + grid[0], dy:dy + grid[1], dx:dx + grid[2]]
                    all_above &= above[dz:dz + grid[0], dy:dy + grid[1], dx:dx + grid[2]]
        crossing = ~(all_below | all_above)
    blocks = []
    for index in zip(*np.nonzero(crossing)):
        start = tuple(int(starts[a][index[a]]) for a in range(3))
        stop = tuple(min(start[a] + chunks[a] + 1, shape[a]) for a in range(3))
        blocks.append((start, stop))
    return blocks, int(crossing.size - crossing.sum())


def _read(store: str, level: str, start, stop) -> np.ndarray:
    import zarr

    array = zarr.open_array(f"{store}/{level}" if level else store, mode="r")
    return np.asarray(array[start[0]:stop[0], start[1]:stop[1], start[2]:stop[2]])


def _block_task(store: str, level: str, start, stop, iso: float, shape, spacing, origin):
    """One Dask task: read the block (overlap included) and mesh its cells with global keys."""
    from algorithms.surfaces.marching_cubes.blocks import marching_cubes_block

    block = _read(store, level, start, stop)
    return marching_cubes_block(block, iso, start=start, volume_shape=shape, spacing=spacing, origin=origin,
                                threads=1)


def _range_task(store: str, level: str, start, stop):
    block = _read(store, level, start, stop)
    return float(block.min()), float(block.max())


def _gather(client, function, calls, progress, share):
    """Run ``function(*call)`` for every call; yield results as they finish, reporting progress; cancel on
    OperationCancelled."""
    if client is None:
        for n, call in enumerate(calls):
            yield function(*call)
            if progress is not None:
                progress(share[0] + (share[1] - share[0]) * (n + 1) / len(calls))
        return
    from distributed import as_completed

    futures = [client.submit(function, *call, pure=False) for call in calls]
    try:
        for n, future in enumerate(as_completed(futures)):
            result = future.result()
            future.release()
            yield result
            if progress is not None:
                progress(share[0] + (share[1] - share[0]) * (n + 1) / len(calls))
    except BaseException:
        client.cancel(futures)
        raise


def mesh_chunked(chunked, iso: float, *, client=None, level: int = 0,
                 progress: Callable[[float], None] | None = None) -> ChunkedMesh:
    """Marching cubes of a :class:`~app.io.zarr.ChunkedVolume` level, one Dask task per storage chunk.

    Parameters
    ----------
    chunked : ChunkedVolume
        The store (read by the workers at ``chunked.path``: on a cluster, a path every worker sees).
    iso : float
        Isovalue (inside is ``value >= iso``).
    client : distributed.Client, optional
        Where the tasks run; None runs them here, one after the other (same tasks, same stitching).
    progress : callable, optional
        Fraction done; raising ``OperationCancelled`` from it cancels the remaining futures.

    Returns
    -------
    ChunkedMesh
        Equal to :func:`algorithms.surfaces.marching_cubes.marching_cubes` of the whole level (same triangles,
        same shared vertices), without normals.
    """
    started = time.perf_counter()
    lv = chunked.levels[level]
    shape, chunks = lv.shape, lv.chunks
    store, name = str(chunked.path), lv.name
    ranges = chunked.chunk_range() if level == 0 else None
    first_pass = False
    if ranges is None:  # a first pass of min/max per chunk (overlap excluded: the plan adds the neighbours)
        first_pass = True
        starts = _starts(shape, chunks)
        calls = [(store, name, (z, y, x), (min(z + chunks[0], shape[0]), min(y + chunks[1], shape[1]),
                                           min(x + chunks[2], shape[2])))
                 for z in starts[0] for y in starts[1] for x in starts[2]]
        if client is None:
            values = [_range_task(*call) for call in calls]
        else:
            values = client.gather(client.map(_range_task, *zip(*calls), pure=False))
        if progress is not None:
            progress(0.2)
        ranges = np.asarray(values, dtype=np.float64).reshape(len(starts[0]), len(starts[1]), len(starts[2]), 2)
    blocks, skipped = plan_blocks(shape, chunks, float(iso), ranges)
    stitcher = Stitcher()
    calls = [(store, name, start, stop, float(iso), shape, lv.spacing, lv.origin) for start, stop in blocks]
    share = (0.2 if first_pass else 0.0, 0.95)
    for piece in _gather(client, _block_task, calls, progress, share):
        stitcher.add(piece)
    meshed = time.perf_counter()
    points, _, triangles = stitcher.merged()
    if progress is not None:
        progress(1.0)
    workers = len(client.scheduler_info().get("workers", {})) if client is not None else 0
    stats = {"blocks": len(blocks) + skipped, "blocks_meshed": len(blocks), "blocks_skipped": skipped,
             "chunks": list(chunks[::-1]), "first_pass": first_pass, "workers": workers,
             "mesh_seconds": meshed - started, "stitch_seconds": time.perf_counter() - meshed,
             "points": int(points.shape[0]), "triangles": int(triangles.shape[0])}
    return ChunkedMesh(points, triangles, stats)
