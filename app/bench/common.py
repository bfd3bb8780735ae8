"""Shared benchmark machinery: timing, machine description, CSV and plots."""

from __future__ import annotations

import csv
import gc
import json
import os
import platform
import statistics
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence


@dataclass
class Timing:
    """Wall-clock seconds of repeated calls (after warm-up calls that are not counted)."""

    samples: list[float]

    @property
    def median(self) -> float:
        return statistics.median(self.samples)

    @property
    def mean(self) -> float:
        return statistics.fmean(self.samples)

    @property
    def minimum(self) -> float:
        return min(self.samples)

    @property
    def p95(self) -> float:
        ordered = sorted(self.samples)
        return ordered[min(len(ordered) - 1, int(round(0.95 * (len(ordered) - 1))))]

    @property
    def weighted_mean(self) -> float:
        """Frame-time-weighted mean, sum(t^2) / sum(t): each frame weighted by how long it stays on screen (source 001)."""
        total = sum(self.samples)
        return sum(t * t for t in self.samples) / total if total > 0 else 0.0


def time_call(function: Callable[[], Any], *, repeats: int = 5, warmup: int = 1) -> tuple[Timing, Any]:
    """Call ``function`` ``warmup`` times untimed, then ``repeats`` times timed; returns timings and the last result."""
    result = None
    for _ in range(warmup):
        result = function()
    samples = []
    for _ in range(repeats):
        gc.collect()
        start = time.perf_counter()
        result = function()
        samples.append(time.perf_counter() - start)
    return Timing(samples), result


def machine_info() -> dict[str, Any]:
    """What the numbers were measured on."""
    import numpy
    import vtk

    from ..vtk_setup import smp_backend

    info = {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "numpy": numpy.__version__,
        "vtk": vtk.vtkVersion.GetVTKVersion(),
        "vtk_smp_backend": smp_backend(),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    try:
        import numba

        info["numba"] = numba.__version__
        info["numba_threads"] = numba.config.NUMBA_NUM_THREADS
    except ImportError:  # pragma: no cover - numba is a dependency
        pass
    return info


def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Iterable[str] | None = None) -> Path:
    """Write dictionaries as CSV (columns: the given order, else the union of keys in first-seen order)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if columns is None:
        columns = []
        for row in rows:
            for key in row:
                if key not in columns:
                    columns.append(key)
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(columns), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _format(v) for k, v in row.items()})
    return path


def _format(value):
    if isinstance(value, float):
        return f"{value:.6g}"
    return value


def write_json(path: Path, data: Any) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, default=str) + "\n")
    return path


def save_figure(figure, path: Path, *, dpi: int = 120) -> Path:
    """Lay out, write and close a matplotlib figure; returns ``path``."""
    figure.tight_layout()
    figure.savefig(path, dpi=dpi)
    pyplot().close(figure)
    return Path(path)


def pyplot():
    """matplotlib's pyplot with the non-interactive Agg back end (benchmarks run headless)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt
