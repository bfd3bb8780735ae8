"""Benchmark: our marching cubes against vtkMarchingCubes and vtkFlyingEdges3D, in the same run.

Cases
-----
- The CT sample (the FORBILD head, 512 x 512 x 176, int16 HU; quick: on 256 x 256 x 88 voxels) at 300 HU (bone)
  and -300 HU (skin), with
  and without normals.
- Colin 27 (181 x 217 x 181 T1 MR, uint8) at Voxelscope's default isovalue for it.
- Synthetic noisy tori (float32) of 64^3 to 512^3 samples (quick: up to 128^3), surface only.

Every method extracts the same surface from the same samples. VTK runs with ComputeScalars off (and
ComputeGradients off) and ComputeNormals as stated; ``vtkFlyingEdges3D`` is SMP-parallel and runs with VTK's
Sequential and STDThread back ends. Ours uses numba's threads (``numba_threads`` in the JSON).

Measured
--------
- ``median_s``/``min_s``: wall time of the extraction over ``repeats`` calls after one untimed warm-up (input
  conversion excluded: VTK gets a ``vtkImageData`` made beforehand, ours the NumPy array).
- ``ratio_to_ours``: the method's median time over ours (above 1: ours is faster).
- Ours and ``vtkFlyingEdges3D`` with VTK's threads (the comparison the issue asks for) are timed in turns: each
  repeat calls both, the order alternating, so a change of load during the run falls on both alike.
  ``paired_ratio_to_ours`` is the median over repeats of that repeat's flying-edges time over ours; the JSON
  summary gives ours over flying edges both ways (ratio of medians, and paired).
- ``triangles_per_s``: triangles / median time.
- ``peak_mb``: for ours, the peak of Python-tracked allocations during one call (``tracemalloc``: NumPy arrays,
  i.e. outputs and temporaries; numba's per-thread id planes, a few MB, are not tracked). For VTK, tracemalloc
  cannot see C++ allocations, so ``peak_mb`` is empty and ``output_mb`` (``GetActualMemorySize`` of the output)
  is given for every method instead.
- ``first_call_s``: the first call in this process, before the warm-up: for ours it includes loading numba's
  compiled kernels from the on-disk cache, or compiling them when there is no cache (see ``numba_cache`` in
  the JSON: hits and misses per kernel).
- ``numba_compile_s`` (JSON): numba's compile time proper, per volume dtype, measured in a separate Python
  process with an empty cache directory (first call on a small volume minus a second call).
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any, Callable

import numpy as np

from algorithms.common.progress import ProgressCallback, report
from algorithms.common.vtk_bridge import image_from_array, run_algorithm
from app.datasets import torus_field
from app.io import load_volume
from app.volume import default_iso

from ..vtk_setup import configure_vtk, set_smp_backend, smp_backend
from .common import (ct_volume, machine_info, paired_ratio, pyplot, save_figure, time_call, time_interleaved, write_csv,
                     write_json)

COLIN27 = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "colin27_t1_ch2.nii.gz"
SYNTHETIC_SIZES = (64, 128, 192, 256, 384, 512)
QUICK_SYNTHETIC_SIZES = (64, 96, 128)
COLUMNS = (
    "dataset", "shape", "voxels", "iso", "normals", "method", "backend", "median_s", "min_s", "repeats",
    "paired_ratio_to_ours",
    "ratio_to_ours", "triangles", "points", "triangles_per_s", "peak_mb", "output_mb", "first_call_s",
)


def noisy_torus(n: int, *, seed: int = 0) -> np.ndarray:
    """A torus field on an ``n``^3 grid (level 0, major radius 0.3 n, minor 0.12 n voxels) with Gaussian noise of
    0.3 voxel, float32: a smooth surface with small bumps, like a segmented organ."""
    field = torus_field((n, n, n), 0.3 * n, 0.12 * n)
    noise = np.random.default_rng(seed).standard_normal(field.shape, dtype=np.float32)
    noise *= 0.3
    field += noise
    return field


def _cases(quick: bool):
    """(dataset name, loader, with normals too); a loader returns the array, spacing, origin and isovalues."""

    def ct():
        volume = ct_volume(quick)
        return volume.array, volume.spacing, volume.origin, (300.0, -300.0)

    def colin():
        volume = load_volume(COLIN27)
        return volume.array, volume.spacing, volume.origin, (round(default_iso(volume), 1),)

    cases = [("CT phantom", ct, True)]
    if COLIN27.exists():
        cases.append(("Colin 27 T1", colin, False))
    for n in QUICK_SYNTHETIC_SIZES if quick else SYNTHETIC_SIZES:
        cases.append((f"noisy torus {n}^3", lambda n=n: (noisy_torus(n), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), (0.0,)),
                      False))
    return cases


_COMPILE_PROBE = """
import sys, time
import numpy as np
from algorithms.surfaces.marching_cubes import marching_cubes
volume = (np.indices((12, 13, 14)).sum(axis=0) % 7).astype(sys.argv[1])
start = time.perf_counter()
marching_cubes(volume, 3.5, normals=True)
first = time.perf_counter() - start
start = time.perf_counter()
marching_cubes(volume, 3.5, normals=True)
print(first - (time.perf_counter() - start))
"""


def numba_compile_seconds(dtypes) -> dict[str, float]:
    """Compile time of our kernels for each volume dtype, in a fresh process with an empty numba cache."""
    seconds = {}
    for dtype in dtypes:
        with tempfile.TemporaryDirectory() as cache:
            environment = dict(os.environ, NUMBA_CACHE_DIR=cache)
            result = subprocess.run([sys.executable, "-c", _COMPILE_PROBE, np.dtype(dtype).name], env=environment,
                                    capture_output=True, text=True, check=True)
            seconds[np.dtype(dtype).name] = float(result.stdout.strip())
    return seconds


def _repeats(voxels: int, quick: bool) -> int:
    if quick:
        return 3
    return 31 if voxels <= 16_000_000 else 5


def _ours(array, iso, spacing, origin, normals):
    from algorithms.surfaces.marching_cubes import marching_cubes

    def extract():
        return marching_cubes(array, iso, spacing=spacing, origin=origin, normals=normals)

    return extract


def _vtk(algorithm_class, image, iso, normals):
    algorithm = algorithm_class()
    algorithm.SetInputData(image)
    algorithm.SetValue(0, iso)
    algorithm.SetComputeNormals(int(normals))
    algorithm.SetComputeScalars(0)
    algorithm.SetComputeGradients(0)

    def extract():
        algorithm.Modified()
        return run_algorithm(algorithm)

    return extract


def _measure(extract: Callable[[], Any], repeats: int) -> tuple[float, Any, Any]:
    start = time.perf_counter()
    extract()
    first = time.perf_counter() - start
    timing, result = time_call(extract, repeats=repeats, warmup=1)
    return first, timing, result


def _measure_pair(first_extract: Callable[[], Any], second_extract: Callable[[], Any], repeats: int):
    """First calls (each timed alone), then both timed in turns: ((first s, timing, result) per function)."""
    firsts = []
    for extract in (first_extract, second_extract):
        start = time.perf_counter()
        extract()
        firsts.append(time.perf_counter() - start)
    timings, results = time_interleaved([first_extract, second_extract], repeats=repeats, warmup=1)
    return [(firsts[n], timings[n], results[n]) for n in range(2)]


def _counts(result) -> tuple[int, int, float]:
    """Triangles, points and output size (MB) of our mesh or a VTK polydata."""
    if hasattr(result, "triangles"):
        size = result.points.nbytes + result.triangles.nbytes + result.values.nbytes
        size += result.normals.nbytes if result.normals is not None else 0
        return len(result.triangles), len(result.points), size / 2**20
    return int(result.GetNumberOfCells()), int(result.GetNumberOfPoints()), result.GetActualMemorySize() / 1024


def _peak_mb(extract: Callable[[], Any]) -> float:
    tracemalloc.start()
    try:
        extract()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Time the three extractors on every case; write CSV, a log-log plot and JSON to ``out_dir``."""
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D, vtkMarchingCubes

    ours_module = importlib.import_module("algorithms.surfaces.marching_cubes.kernels")

    configure_vtk()
    initial_backend = smp_backend()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cases = _cases(quick)
    rows: list[dict[str, Any]] = []
    compile_seconds = numba_compile_seconds(("int16",) if quick else ("int16", "uint8", "float32"))
    try:
        for index, (dataset, load, with_normals_too) in enumerate(cases):
            array, spacing, origin, levels = load()
            image = image_from_array(array, spacing, origin)
            repeats = _repeats(array.size, quick)
            for iso in levels:
                for normals in (False, True) if with_normals_too else (False,):
                    base = {"dataset": dataset, "shape": "x".join(map(str, array.shape[::-1])), "voxels": array.size,
                            "iso": iso, "normals": normals, "repeats": repeats}
                    extract = _ours(array, iso, spacing, origin, normals)
                    set_smp_backend("STDThread")
                    (first, timing, mesh), (fe_first, fe_timing, fe_output) = _measure_pair(
                        extract, _vtk(vtkFlyingEdges3D, image, iso, normals), repeats)
                    ours_timing = timing
                    triangles, points, output_mb = _counts(mesh)
                    ours_median = timing.median
                    rows.append({**base, "method": "ours", "backend": "numba threads", "median_s": timing.median,
                                 "min_s": timing.minimum, "triangles": triangles, "points": points,
                                 "triangles_per_s": triangles / timing.median, "peak_mb": _peak_mb(extract),
                                 "output_mb": output_mb, "first_call_s": first, "ratio_to_ours": 1.0,
                                 "paired_ratio_to_ours": 1.0})
                    measured = {("vtkFlyingEdges3D", "STDThread"): (fe_first, fe_timing, fe_output)}
                    for method, algorithm_class, backend in (
                        ("vtkMarchingCubes", vtkMarchingCubes, "Sequential"),
                        ("vtkFlyingEdges3D", vtkFlyingEdges3D, "Sequential"),
                        ("vtkFlyingEdges3D", vtkFlyingEdges3D, "STDThread"),
                    ):
                        if (method, backend) in measured:
                            first, timing, output = measured[method, backend]
                            paired = paired_ratio(timing, ours_timing)
                        else:
                            set_smp_backend(backend)
                            first, timing, output = _measure(_vtk(algorithm_class, image, iso, normals), repeats)
                            paired = ""
                        triangles, points, output_mb = _counts(output)
                        rows.append({**base, "method": method, "backend": backend, "median_s": timing.median,
                                     "min_s": timing.minimum, "triangles": triangles, "points": points,
                                     "triangles_per_s": triangles / timing.median, "peak_mb": "",
                                     "output_mb": output_mb, "first_call_s": first,
                                     "ratio_to_ours": timing.median / ours_median, "paired_ratio_to_ours": paired})
            del array, image
            report(progress, (index + 1) / len(cases))
    finally:
        set_smp_backend(initial_backend)

    csv_path = write_csv(out_dir / "marching_cubes.csv", rows, COLUMNS)
    plot_path = _plot(rows, out_dir / "marching_cubes.png")
    info = machine_info()
    info["vtk_smp_backend"] = "varies per row (see backend); restored to " + initial_backend
    kernels = ("count_layers", "fill_layers", "merge_on_samples")
    json_path = write_json(out_dir / "marching_cubes.json", {
        "benchmark": "marching-cubes",
        "quick": quick,
        "machine": info,
        "numba_compile_s": compile_seconds,
        "numba_cache": {name: {"hits": sum(getattr(ours_module, name).stats.cache_hits.values()),
                               "misses": sum(getattr(ours_module, name).stats.cache_misses.values())}
                        for name in kernels},
        "ours_over_flying_edges_stdthread": _summary(rows),
        "notes": __doc__,
        "rows": rows,
    })
    return [csv_path, plot_path, json_path]


def _summary(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per case: our median time over vtkFlyingEdges3D's with VTK's threads (STDThread), timed in turns in the same
    run (at most 1.0: ours is as fast or faster); ``paired_ratio``: the median of the per-repeat ratios."""
    summary = []
    for row in rows:
        if row["method"] != "ours":
            continue
        match = next(other for other in rows if other["method"] == "vtkFlyingEdges3D"
                     and other["backend"] == "STDThread"
                     and all(other[key] == row[key] for key in ("dataset", "iso", "normals")))
        summary.append({"dataset": row["dataset"], "iso": row["iso"], "normals": row["normals"],
                        "ours_ms": 1e3 * row["median_s"], "flying_edges_stdthread_ms": 1e3 * match["median_s"],
                        "ratio": row["median_s"] / match["median_s"],
                        "paired_ratio": 1.0 / match["paired_ratio_to_ours"]})
    return summary


def _plot(rows: list[dict[str, Any]], path: Path) -> Path:
    plt = pyplot()
    figure, (series, bars) = plt.subplots(1, 2, figsize=(13, 5))
    synthetic = [row for row in rows if row["dataset"].startswith("noisy torus")]
    for label in sorted({(row["method"], row["backend"]) for row in synthetic}):
        points = sorted((row["voxels"], row["median_s"]) for row in synthetic if (row["method"], row["backend"]) == label)
        series.loglog(*zip(*points), marker="o", label=f"{label[0]} ({label[1]})")
    series.set_xlabel("voxels")
    series.set_ylabel("extraction time, median (s)")
    series.set_title("Noisy torus, surface only")
    series.grid(True, which="both", alpha=0.3)
    series.legend(fontsize=8)

    named = [row for row in rows if not row["dataset"].startswith("noisy torus")]
    groups = sorted({(row["dataset"], row["iso"], row["normals"]) for row in named}, key=str)
    methods = sorted({(row["method"], row["backend"]) for row in named})
    width = 0.8 / max(len(methods), 1)
    for m, method in enumerate(methods):
        times = [next((row["median_s"] * 1e3 for row in named
                       if (row["dataset"], row["iso"], row["normals"]) == group
                       and (row["method"], row["backend"]) == method), np.nan) for group in groups]
        bars.bar(np.arange(len(groups)) + m * width, times, width, label=f"{method[0]} ({method[1]})")
    bars.set_xticks(np.arange(len(groups)) + 0.4 - width / 2)
    bars.set_xticklabels([f"{d}\n{iso:g}{' HU' if 'CT' in d else ''}{', normals' if n else ''}"
                          for d, iso, n in groups], fontsize=7)
    bars.set_yscale("log")
    bars.set_ylabel("extraction time, median (ms)")
    bars.set_title("Real-sized volumes")
    bars.legend(fontsize=8)
    return save_figure(figure, path)
