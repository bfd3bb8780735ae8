"""Writing an OME-Zarr pyramid from a block generator, chunk by chunk in parallel processes.

For volumes made by a formula (the synthetic benchmark volumes of issue 19, 2048^3 = 16 GiB of uint16): every level-0
chunk is computed by ``make_block(z0, z1, y0, y1, x0, x1)`` (sample ranges, ``(nz, ny, nx)`` order) inside a worker
process and written straight to its Zarr chunk, so no process ever holds more than a row of chunks. Pyramid level
``n`` is then computed from the *stored* level ``n - 1``, one output chunk at a time: the 2x2x2 block means of the
region of level ``n - 1`` under that chunk, in the same arithmetic as :func:`app.io.zarr.write_ome_zarr` (float64
mean, rounded for integers), so both writers give the same samples and metadata (geometry as documented in
:mod:`app.io.zarr`; OME-NGFF 0.4/0.5, J. Moore et al., "OME-NGFF: a next-generation file format for expanding
bioimaging data-access strategies", 2021).
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import FileExistsRefusal
from .zarr import _compressor, _create_levels, _datasets, _pyramid_shapes, _write_attributes, written_in_place

__all__ = ["write_ome_zarr_blocks", "halve_block"]


def halve_block(block: np.ndarray, dtype) -> np.ndarray:
    """Mean of 2x2x2 blocks of an even-sided ``(nz, ny, nx)`` block (float64, rounded for integer types)."""
    nz, ny, nx = (s // 2 for s in block.shape)
    mean = block.reshape(nz, 2, ny, 2, nx, 2).astype(np.float64).mean(axis=(1, 3, 5))
    dtype = np.dtype(dtype)
    return np.round(mean).astype(dtype) if dtype.kind in "iu" else mean.astype(dtype)


def _chunk_ranges(shape, chunks):
    return [[(c, min(c + chunks, s)) for c in range(0, s, chunks)] for s in shape]


def _write_row(make_block, array_path: str, rows: tuple, columns: list) -> list[tuple[float, float]]:
    """Worker: compute and write one row of level-0 chunks; their minima and maxima."""
    import zarr

    array = zarr.open_array(array_path, mode="r+")
    (z0, z1), (y0, y1) = rows
    ranges = []
    for x0, x1 in columns:
        block = np.asarray(make_block(z0, z1, y0, y1, x0, x1))
        if block.shape != (z1 - z0, y1 - y0, x1 - x0):
            raise ValueError(f"the block generator returned shape {block.shape} for "
                             f"{(z1 - z0, y1 - y0, x1 - x0)}")
        array[z0:z1, y0:y1, x0:x1] = block
        ranges.append((float(block.min()), float(block.max())))
    return ranges


def _halve_row(source_path: str, target_path: str, rows: tuple, columns: list) -> int:
    """Worker: one row of chunks of level ``n`` from the stored level ``n - 1``."""
    import zarr

    source = zarr.open_array(source_path, mode="r")
    target = zarr.open_array(target_path, mode="r+")
    (z0, z1), (y0, y1) = rows
    for x0, x1 in columns:
        block = np.asarray(source[2 * z0:2 * z1, 2 * y0:2 * y1, 2 * x0:2 * x1])
        target[z0:z1, y0:y1, x0:x1] = halve_block(block, target.dtype)
    return len(columns)


def _run(pool, workers: int, tasks, on_done: Callable) -> None:
    """Submit ``(function, args)`` tasks, keep at most 2 per worker in flight, call ``on_done(index, result)``."""
    pending = {}
    queue = list(enumerate(tasks))
    limit = 2 * workers
    try:
        while queue or pending:
            while queue and len(pending) < limit:
                index, (function, args) = queue.pop(0)
                pending[pool.submit(function, *args)] = index
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_done(pending.pop(future), future.result())
    finally:
        for future in pending:
            future.cancel()


def write_ome_zarr_blocks(make_block: Callable, shape, dtype, path, *, spacing=(1.0, 1.0, 1.0),
                          origin=(0.0, 0.0, 0.0), direction=None, chunks: int = 128,
                          compressor: str = "blosc-zstd", levels: int | None = None, zarr_format: int = 2,
                          modality: str = "", units: str = "", overwrite: bool = False, workers: int = 2,
                          progress: Callable[[float], None] | None = None) -> Path:
    """Write the volume ``make_block`` describes as an OME-Zarr pyramid, atomically, with ``workers`` processes.

    Parameters
    ----------
    make_block : callable
        ``make_block(z0, z1, y0, y1, x0, x1) -> ndarray (z1 - z0, y1 - y0, x1 - x0)``; picklable (a module-level
        function or a ``functools.partial`` of one), since it runs in worker processes.
    shape : (nz, ny, nx)
    dtype : numpy dtype of the samples
    Other parameters as :func:`app.io.zarr.write_ome_zarr`. ``progress`` may raise ``OperationCancelled``: the
    remaining tasks are cancelled and the temporary store removed.
    """
    import zarr

    path = Path(path).expanduser()
    shape = tuple(int(s) for s in shape)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"a volume needs a 3D shape (nz, ny, nx), got {shape}")
    if zarr_format not in (2, 3):
        raise ValueError(f"zarr_format must be 2 or 3, got {zarr_format!r}")
    chunks, workers = int(chunks), int(workers)
    if chunks < 8:
        raise ValueError(f"chunks must be at least 8 samples, got {chunks}")
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if path.exists() and not overwrite:
        raise FileExistsRefusal(path)
    dtype = np.dtype(dtype)
    codec = _compressor(compressor, zarr_format)
    shapes = _pyramid_shapes(shape, 128)
    if levels is not None:
        if int(levels) < 1:
            raise ValueError(f"levels must be at least 1, got {levels}")
        shapes = shapes[: int(levels)] if int(levels) <= len(shapes) else _pyramid_shapes(shape, 1)[: int(levels)]
    spacing = np.asarray(spacing, float)
    origin = np.asarray(origin, float)
    direction = np.eye(3) if direction is None else np.asarray(direction, float).reshape(3, 3)
    # Work per level: level 0 costs the formula plus compression; each further level 1/8 of the one before.
    weights = np.array([1.0] + [0.5 / 8 ** n for n in range(1, len(shapes))])
    weights /= weights.sum()
    with written_in_place(path) as temporary:
        group = zarr.open_group(temporary, mode="w", zarr_format=zarr_format)
        arrays = _create_levels(group, shapes, chunks, dtype, codec, zarr_format)
        grid = _chunk_ranges(shape, arrays[0].chunks[0])
        counts = [len(g) for g in grid]
        chunk_range = np.zeros((*counts, 2), np.float64)
        context = multiprocessing.get_context("spawn")  # zarr's I/O threads make fork unsafe
        with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            rows = [(a, b) for a in range(counts[0]) for b in range(counts[1])]
            tasks = [(_write_row, (make_block, str(temporary / "0"), (grid[0][a], grid[1][b]), grid[2]))
                     for a, b in rows]

            def level0_done(index, ranges):
                a, b = rows[index]
                chunk_range[a, b, :, :] = ranges
                if progress is not None:
                    progress(weights[0] * (level0_done.count + 1) / len(tasks))
                level0_done.count += 1

            level0_done.count = 0
            _run(pool, workers, tasks, level0_done)
            for n in range(1, len(shapes)):
                level_grid = _chunk_ranges(shapes[n], arrays[n].chunks[0])
                tasks = [(_halve_row, (str(temporary / str(n - 1)), str(temporary / str(n)), (za, yb),
                                       level_grid[2])) for za in level_grid[0] for yb in level_grid[1]]
                before, share, total = weights[:n].sum(), weights[n], len(tasks)

                def level_done(index, _, before=before, share=share, total=total, state=[0]):
                    state[0] += 1
                    if progress is not None:
                        progress(before + share * state[0] / total)

                _run(pool, workers, tasks, level_done)
        group.create_array("chunk_range", data=chunk_range, chunks=chunk_range.shape, compressors=None)
        _write_attributes(group, path, _datasets(shapes, spacing, origin), spacing, origin, direction, modality,
                          units, chunk_range, zarr_format)
    if progress is not None:
        progress(1.0)
    return path
