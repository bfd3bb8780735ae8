"""Benchmark: chunked marching cubes on a Dask cluster - peak memory of all processes, throughput against workers,
and the overhead of the distributed path against the in-memory one (issue 19).

Volume
------
A synthetic uint16 OME-Zarr (:func:`synthetic_store`): a gyroid (period 840 samples at 1024^3) inside a ball of radius
0.41 n, values around 32768 with isovalue 32768, written chunk by chunk (128^3 chunks, blosc-zstd): each chunk is
computed from the formula in one of 2 worker processes and written straight to the store, pyramid levels are block
means of the stored level above (:mod:`app.io.zarr_blocks`), so generating it never holds more than a row of
chunks. Full run: 1024^3 (2 GiB of samples); quick: 256^3 (32 MiB).

Commands
--------
``python -m app.cli mesh VOLUME.zarr --method marching-cubes --iso 32768 --workers N -o out.vtp --json`` in a fresh
process, for N = 1 and 2, and the in-memory path ``mesh VOLUME.nii`` on a volume that fits (quick size).

Measured
--------
``peak_all_mib``: the largest sum of the resident set sizes of the command and every process it started (client,
nanny and worker processes), sampled every 50 ms with psutil; ``sum_of_peaks_mib``: the sum of each process's own
peak (an upper bound); ``seconds`` (wall time of the whole command, cluster start included), ``mesh_seconds``
(the Dask part as the command reports it), triangles, blocks meshed and skipped. One run per configuration.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import threading
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.progress import ProgressCallback, report

from ..io import save_volume
from ..io.zarr import read_zarr
from ..io.zarr_blocks import write_ome_zarr_blocks
from .common import machine_info, write_csv, write_json

SIZE = 1024
QUICK_SIZE = 256
ISO = 32768.0
COLUMNS = ("command", "workers", "size", "peak_all_mib", "sum_of_peaks_mib", "volume_mib", "seconds", "mesh_seconds",
           "triangles", "points", "blocks_meshed", "blocks_skipped", "exit_code")


def synthetic_block(n: int, z0: int, z1: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
    """Samples ``[z0:z1, y0:y1, x0:x1]`` of the ``n^3`` benchmark volume (uint16), from its formula."""
    z, y, x = np.ogrid[z0:z1, y0:y1, x0:x1]
    scale = 2 * np.pi / 840.0 * (1024.0 / n)  # the same shape at every size
    gyroid = (np.sin(x * scale) * np.cos(y * scale) + np.sin(y * scale) * np.cos(z * scale)
              + np.sin(z * scale) * np.cos(x * scale))
    centre = (n - 1) / 2
    radius = np.sqrt((x - centre) ** 2 + (y - centre) ** 2 + (z - centre) ** 2) / n
    values = 32768.0 + 12000.0 * gyroid - 400000.0 * np.maximum(radius - 0.41, 0.0)
    return np.clip(np.round(values), 0, 65535).astype(np.uint16)


def _synthetic_block(block_info=None):
    (z0, z1), (y0, y1), (x0, x1) = block_info[None]["array-location"]
    return synthetic_block(block_info[None]["shape"][0], z0, z1, y0, y1, x0, x1)


def synthetic_array(n: int, chunks: int = 128):
    """The benchmark volume as a lazy ``(n, n, n)`` uint16 dask array (computed chunk by chunk)."""
    import dask.array as da

    return da.map_blocks(_synthetic_block, dtype=np.uint16,
                         chunks=da.core.normalize_chunks((chunks,) * 3, (n, n, n)))


def synthetic_store(path: Path, n: int, *, chunks: int = 128, workers: int = 2,
                    progress: ProgressCallback = None) -> Path:
    """Write (once) the synthetic volume as OME-Zarr at ``path`` (0.1 mm voxels); reused when present.

    Each chunk is computed from the formula in one of ``workers`` processes and written straight to the store; the
    pyramid levels are block means of the stored level above, chunk by chunk (:mod:`app.io.zarr_blocks`)."""
    if path.exists():
        return path
    return write_ome_zarr_blocks(partial(synthetic_block, n), (n, n, n), np.uint16, path, spacing=(0.1, 0.1, 0.1),
                                 chunks=chunks, workers=workers, progress=progress)


def peak_of_tree(arguments: list[str], *, interval: float = 0.05, stderr=subprocess.PIPE) -> dict[str, Any]:
    """Run a command; the peak of the summed RSS of it and all its descendants, and the sum of their own peaks.

    ``stderr``: where the command's standard error goes (captured by default; a terminal's descriptor shows its
    progress line)."""
    import psutil

    start = time.perf_counter()
    process = subprocess.Popen(arguments, stdout=subprocess.PIPE, stderr=stderr, text=True)
    root = psutil.Process(process.pid)
    peaks: dict[int, int] = {}
    peak_all = [0]
    done = threading.Event()

    def sample():
        while not done.is_set():
            total = 0
            try:
                members = [root, *root.children(recursive=True)]
            except psutil.Error:
                members = []
            for member in members:
                try:
                    rss = member.memory_info().rss
                except psutil.Error:
                    continue
                total += rss
                peaks[member.pid] = max(peaks.get(member.pid, 0), rss)
            peak_all[0] = max(peak_all[0], total)
            done.wait(interval)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    stdout, stderr = process.communicate()
    done.set()
    sampler.join()
    return {"peak_all_mib": peak_all[0] / 2**20, "sum_of_peaks_mib": sum(peaks.values()) / 2**20,
            "processes": len(peaks), "seconds": time.perf_counter() - start, "exit_code": process.returncode,
            "stdout": stdout, "stderr": stderr}


def _mesh_row(name: str, arguments: list[str], size: int, workers: int, volume_mib: float,
              **options) -> dict[str, Any]:
    measured = peak_of_tree(arguments, **options)
    row = {"command": name, "workers": workers, "size": size, "volume_mib": volume_mib,
           **{k: measured[k] for k in ("peak_all_mib", "sum_of_peaks_mib", "seconds", "exit_code")}}
    if measured["exit_code"] == 0:
        data = json.loads(measured["stdout"])
        chunked = data.get("chunked", {})
        row.update(triangles=data["triangles"], points=data["points"], mesh_seconds=chunked.get("mesh_seconds"),
                   blocks_meshed=chunked.get("blocks_meshed"), blocks_skipped=chunked.get("blocks_skipped"))
    else:
        row["error"] = (measured["stderr"] or "").strip().splitlines()[-1:]
    return row


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None, size: int | None = None,
        keep: bool = False) -> list[Path]:
    """Generate the volume, mesh it with 1 and 2 workers (and in memory at the quick size); CSV and JSON."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    size = size or (QUICK_SIZE if quick else SIZE)
    store = out_dir / f"synthetic_{size}.zarr"
    started = time.perf_counter()
    synthetic_store(store, size, progress=lambda f: report(progress, 0.3 * f))
    generated = time.perf_counter() - started
    volume_mib = size ** 3 * 2 / 2**20
    rows = []
    cli = [sys.executable, "-m", "app.cli", "mesh"]
    for n, workers in enumerate((2, 1)):
        output = out_dir / f"mesh_{size}_w{workers}.vtp"
        rows.append(_mesh_row("mesh zarr", cli + [str(store), "--method", "marching-cubes", "--iso", str(ISO),
                                                  "--workers", str(workers), "-o", str(output), "--force", "--json"],
                              size, workers, volume_mib))
        report(progress, 0.3 + 0.3 * (n + 1))
    if size <= 384:  # the in-memory path on the same volume, for the overhead

        nifti = out_dir / f"synthetic_{size}.nii"
        if not nifti.exists():
            save_volume(read_zarr(store), nifti)
        rows.append(_mesh_row("mesh in memory", cli + [str(nifti), "--method", "marching-cubes", "--iso", str(ISO),
                                                       "-o", str(out_dir / f"mesh_{size}_memory.vtp"), "--force",
                                                       "--json"], size, 0, volume_mib))
    csv_path = write_csv(out_dir / "chunked.csv", rows, COLUMNS)
    json_path = write_json(out_dir / "chunked.json", {"machine": machine_info(), "size": size, "iso": ISO,
                                                      "generate_seconds": generated, "rows": rows})
    if not keep:
        shutil.rmtree(store, ignore_errors=True)
    report(progress, 1.0)
    return [csv_path, json_path]
