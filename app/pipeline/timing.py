"""Frame-time statistics (source 001's metrics): median, mean, frame-time-weighted mean and 95th percentile.

Source 001 reports the mean frame time and frame rate and the frame-time-weighted mean ``sum(t^2) / sum(t)``, which
weights each frame by how long it stays on screen, so stutter counts; one-off set-up (mesh extraction, encodings)
is reported apart. The view pipeline, ``voxelscope render --frames`` and the benchmarks all use these.
"""

from __future__ import annotations

import gc
import statistics
import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence


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
        """Frame-time-weighted mean, sum(t^2) / sum(t): each frame weighted by how long it stays on screen."""
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


def time_interleaved(functions: Sequence[Callable[[], Any]], *, repeats: int = 5,
                     warmup: int = 1) -> tuple[list[Timing], list[Any]]:
    """Time several functions in turns: each repeat calls every function once, the order rotating from repeat to
    repeat, so a change of machine load during the run falls on all of them alike (comparisons of one against the
    other stay fair). Returns one :class:`Timing` per function and each one's last result."""
    functions = list(functions)
    results: list[Any] = [None] * len(functions)
    for _ in range(warmup):
        for n, function in enumerate(functions):
            results[n] = function()
    samples: list[list[float]] = [[] for _ in functions]
    for repeat in range(repeats):
        for step in range(len(functions)):
            n = (repeat + step) % len(functions)
            gc.collect()
            start = time.perf_counter()
            results[n] = functions[n]()
            samples[n].append(time.perf_counter() - start)
    return [Timing(s) for s in samples], results


def paired_ratio(numerator: Timing, denominator: Timing) -> float:
    """The median over repeats of ``numerator / denominator`` taken within each repeat (for interleaved timings:
    each repeat's two calls ran under the same load)."""
    return statistics.median(a / b for a, b in zip(numerator.samples, denominator.samples))


@dataclass
class FrameTimes:
    """Per-frame seconds of a turning-camera sequence plus the one-off set-up."""

    setup_seconds: float
    frames: list[float]

    def summary(self) -> dict[str, float]:
        timing = Timing(self.frames)
        return {
            "setup_seconds": self.setup_seconds,
            "frame_seconds": timing.median,
            "mean_frame_seconds": timing.mean,
            "weighted_mean_frame_seconds": timing.weighted_mean,
            "p95_frame_seconds": timing.p95,
            "frames": len(self.frames),
        }
