"""Shared benchmark machinery: timing (from :mod:`app.pipeline.timing`), VTK volume mappers in an off-screen scene,
the machine description, CSV and plots."""

from __future__ import annotations

import csv
import json
import os
import platform
import time
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy

from algorithms.common.camera import Camera

from ..datasets import ct_head_phantom
from ..pipeline import (  # noqa: F401 - re-exported for the benchmarks
    FrameTimes,
    OffscreenScene,
    Timing,
    paired_ratio,
    time_call,
    time_interleaved,
)
from ..pipeline.props import volume_prop
from ..samples import load_sample
from ..vtk_setup import smp_backend


#: The CT of the quick runs: the FORBILD head in the sample's field of view on 256 x 256 x 88 voxels (1.09 x 1.09 x
#: 3 mm), about the size of the earlier sample; full runs measure the sample itself (512 x 512 x 176).
QUICK_CT_SHAPE = (88, 256, 256)


def ct_volume(quick: bool):
    """The CT every benchmark measures: the bundled sample, read from its file, or its quick-run grid."""
    if quick:
        return ct_head_phantom(QUICK_CT_SHAPE)

    return load_sample("ct")


def vtk_mapper_scene(volume, function, mapper: str, size, *, sample_distance: float | None = None,
                     shading: bool | None = False, camera: Camera | None = None) -> OffscreenScene:
    """An off-screen scene holding ``volume`` drawn by VTK's ``"gpu"`` or ``"cpu"`` ray caster (the same prop every
    view uses), its camera set when given. The caller closes it."""
    width, height = (size, size) if isinstance(size, int) else size
    scene = OffscreenScene((width, height))
    scene.add(volume_prop(volume, function, mapper=mapper, sample_distance=sample_distance, shading=shading))
    if camera is not None:
        scene.set_camera(camera)
    return scene


def time_vtk_mapper(volume, function, mapper: str, world_cameras: Sequence[Camera], size, *,
                    sample_distance: float | None = None, shading: bool | None = False) -> dict[str, Any]:
    """Set-up (prop, first render and its read-back at the first camera) and every frame of ``world_cameras``
    (``Render`` plus ``WaitForCompletion``) of a VTK volume mapper; ``times`` is a :class:`FrameTimes` and ``start``
    the first frame as ``(h, w, 3)`` uint8."""
    start = time.perf_counter()
    scene = vtk_mapper_scene(volume, function, mapper, size, sample_distance=sample_distance, shading=shading,
                             camera=world_cameras[0])
    try:
        scene.render()
        first = scene.capture()
        setup = time.perf_counter() - start
        frames = []
        for camera in world_cameras:
            scene.set_camera(camera)
            frames.append(scene.render())
    finally:
        scene.close()
    return {"times": FrameTimes(setup, frames), "start": first}


def machine_info() -> dict[str, Any]:
    """What the numbers were measured on."""
    import vtk

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
