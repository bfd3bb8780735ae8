"""Source 000's experiments (section 9) in VTK: memory and frame time of voxel-face surfaces, and extraction time.

For every family of :data:`app.datasets.FAMILIES` (worst case, spheres, pillars with 0/20/50 % noise, scatter at
20/50 % density) and cubic models of ``n`` voxels per side, and for real data (Colin 27 at a few thresholds and an
atlas-like label volume made from it), this benchmark builds the same surface four ways:

- ``baseline``: :func:`algorithms.surfaces.voxel_faces.voxel_faces`, 4 vertices and 6 indices per face (source "Def");
- ``tower``: :func:`algorithms.surfaces.tower.tower_strips`, strips without indices (source "Tow");
- ``hybrid``: :func:`algorithms.surfaces.tower.hybrid` with L = 10 (source "Hyb");
- ``vtkStripper``: VTK's strip generator on the baseline triangles after merging coincident points
  (:func:`algorithms.references.vtk_surfaces.vtk_stripper`), counted with its shared point list and indices and
  de-indexed (see :func:`algorithms.compare.voxel_surfaces.stripper_memory`);

and measures:

- **memory** as the source counts it (vertex bytes + 16/32-bit index bytes, strips = draw calls), plus what VTK's
  OpenGL2 mapper actually uploads for the same polydata (``vtk_upload_bytes``), for ``memory_models`` random models
  per point (1 for the worst case), vtkStripper on the first ``stripper_models``;
- **frame time** of the baseline (indexed triangles), tower and hybrid polydata in VTK off-screen
  (``vtkRenderWindow.Render`` + ``WaitForCompletion`` per frame, 512 x 512 pixels, camera turning a full circle
  over the frames), mean over ``frames`` frames for each of ``render_models`` models; the first frame (upload)
  is not timed;
- **extraction time** (median of ``timing_repeats``, VTK's of ``vtk_timing_repeats``) of baseline, tower, hybrid
  (from the volume), vtkStripper
  (point merge + stripper, from the baseline's triangles) and VTK's own voxel surface
  (:func:`algorithms.references.vtk_surfaces.vtk_threshold_surface`: ``vtkThreshold`` + ``vtkDataSetSurfaceFilter``
  on a cell-data image built beforehand), the VTK ones with the SMP back end both "STDThread" and "Sequential".

Limits, because the machine has 2 cores and 24 GB shared with others and renders with Mesa's llvmpipe:

- a family's larger sizes are not rendered once a size's slowest representation took more than
  :data:`RENDER_LIMIT_MS` per frame (the source stopped where frames passed 100 ms on its GPU; Mesa's llvmpipe
  software rasteriser on 2 shared cores is far slower, about 100 ms for 3 x 10^4 faces, so the cut is at 200 ms);
- models with more than :data:`MAX_FACES` faces are skipped (the worst case at 256 has 50 M faces: 5 GB for the
  baseline alone); vtkStripper runs only up to :data:`STRIPPER_MAX_FACES` faces (it takes about 6 us a face);
- real volumes are rendered for ``real_frames`` frames; the quick run uses one Colin 27 threshold.

Everything skipped is listed in the JSON. Nothing is asserted: the numbers are written down.

References
----------
Source 000 (the Dutch BSc thesis on voxel models as triangle strips, see ``docs/references.md``), sections 8.2
(datasets) and 9 (experiments).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from scipy import ndimage
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.common.vtk_bridge import image_from_array
from algorithms.compare.voxel_surfaces import memory_usage, stripper_memory
from algorithms.references.vtk_surfaces import vtk_stripper, vtk_threshold_surface
from algorithms.surfaces.tower import hybrid, tower_strips
from algorithms.surfaces.voxel_faces import solid_mask, voxel_faces
from app.samples import MRICRON_COLIN27

from .. import datasets
from ..io import load_volume
from ..pipeline import OffscreenScene
from ..vtk_setup import configure_vtk, set_smp_backend, smp_backend
from .common import Timing, machine_info, pyplot, save_figure, time_call, write_csv, write_json

#: Colin 27 (the source's BrainWeb grid, 181 x 217 x 181, 1 mm, uint8): Debian's mricron-data, then shared data.
COLIN_PATHS = (
    MRICRON_COLIN27,
    Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "colin27_t1_ch2.nii.gz",
)
#: Thresholds on Colin 27's T1 values (0-254): head surface, grey matter and up, white matter.
COLIN_THRESHOLDS = (30, 70, 110)
#: The atlas-like label volume: Colin 27 median-filtered over 3 x 3 x 3 voxels, cut at these values into labels
#: 1-3 (label 0 below the first); the surface is that of label > 0.
LABEL_EDGES = (70, 90, 110)

RENDER_LIMIT_MS = 200.0
MAX_FACES = 32_000_000
STRIPPER_MAX_FACES = 2_000_000
WINDOW_SIZE = (512, 512)
HYBRID_L = 10
VTK_BACKENDS = ("STDThread", "Sequential")
REPRESENTATIONS = ("baseline", "tower", "hybrid")


@dataclass(frozen=True)
class Settings:
    sizes: tuple[int, ...]
    memory_models: int
    stripper_models: int
    render_models: int
    frames: int
    timing_repeats: int  # ours
    vtk_timing_repeats: int  # VTK's paths (seconds each on the larger models)
    colin_thresholds: tuple[int, ...]
    real_frames: int


FULL = Settings(
    sizes=(16, 32, 64, 96, 128, 192, 256),
    memory_models=10,
    stripper_models=2,
    render_models=5,
    frames=100,
    timing_repeats=5,
    vtk_timing_repeats=3,
    colin_thresholds=COLIN_THRESHOLDS,
    real_frames=20,
)
QUICK = Settings(
    sizes=(16, 32, 48, 64),
    memory_models=2,
    stripper_models=1,
    render_models=1,
    frames=20,
    timing_repeats=3,
    vtk_timing_repeats=1,
    colin_thresholds=(70,),
    real_frames=3,
)


# ----------------------------------------------------------------------------------------------------------------
# Measurements
# ----------------------------------------------------------------------------------------------------------------
def _surfaces(mask: np.ndarray) -> dict[str, Any] | None:
    """Baseline, tower and hybrid of one model; None when it has more than :data:`MAX_FACES` faces.

    The tower runs first: it needs less than half of the baseline's memory and gives the face count.
    """
    strips = tower_strips(mask)
    if strips.n_triangles // 2 > MAX_FACES:
        return None
    return {"baseline": voxel_faces(mask), "tower": strips, "hybrid": hybrid(strips, max_strip_vertices=HYBRID_L)}


def _memory_rows(surfaces: dict[str, Any], stripper: bool) -> list[dict[str, Any]]:
    rows = [memory_usage(surface).as_row() for surface in surfaces.values()]
    if stripper:
        rows += [usage.as_row() for usage in stripper_memory(vtk_stripper(surfaces["baseline"]))]
    return rows


class _FrameTimer:
    """Frame times of a polydata in one off-screen window while the camera turns a full circle."""

    def __init__(self) -> None:
        self.scene = OffscreenScene(WINDOW_SIZE, background=(1.0, 1.0, 1.0))

    def __call__(self, polydata, frames: int) -> Timing:
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(polydata)
        actor = vtkActor()
        actor.SetMapper(mapper)
        actor.GetProperty().SetInterpolationToFlat()
        self.scene.clear()
        self.scene.add(actor)
        renderer = self.scene.renderer
        renderer.ResetCamera()
        camera = renderer.GetActiveCamera()
        camera.Elevation(25.0)
        camera.OrthogonalizeViewUp()
        renderer.ResetCameraClippingRange()
        self.scene.render()  # uploads the geometry: not timed
        samples = []
        for _ in range(frames):
            camera.Azimuth(360.0 / frames)
            renderer.ResetCameraClippingRange()
            samples.append(self.scene.render())
        self.scene.clear()
        return Timing(samples)

    def close(self) -> None:
        self.scene.close()


def _render_rows(timer: _FrameTimer, surfaces: dict[str, Any], frames: int) -> list[dict[str, Any]]:
    rows = []
    for name in REPRESENTATIONS:
        surface = surfaces[name]
        timing = timer(surface.to_polydata(), frames)
        rows.append(
            {
                "representation": name,
                "triangles": memory_usage(surface).triangles,
                "frames": frames,
                "mean_ms": 1e3 * timing.mean,
                "median_ms": 1e3 * timing.median,
                "weighted_mean_ms": 1e3 * timing.weighted_mean,
            }
        )
    return rows


def _with_backend(backend: str, function: Callable[[], Any]) -> Callable[[], Any]:
    def call():
        previous = smp_backend()
        set_smp_backend(backend)
        try:
            return function()
        finally:
            set_smp_backend(previous)

    return call


def _extraction_rows(volume, threshold, surfaces: dict[str, Any], settings: Settings, stripper: bool) -> list[dict]:
    """Median extraction seconds of every method on one model (``threshold`` None for a boolean mask)."""
    ours = {
        "baseline": lambda: voxel_faces(volume, threshold=threshold),
        "tower": lambda: tower_strips(volume, threshold=threshold),
        "hybrid": lambda: hybrid(volume, threshold=threshold, max_strip_vertices=HYBRID_L),
    }
    rows = []
    for method, function in ours.items():
        timing, _ = time_call(function, repeats=settings.timing_repeats, warmup=0)
        rows.append({"method": method, "smp_backend": "", "median_s": timing.median})
    values, vtk_threshold = (volume, threshold) if threshold is not None else (volume.astype(np.uint8), 1.0)
    image = image_from_array(values, cell_data=True)
    vtk_methods = {"vtkThreshold+vtkDataSetSurfaceFilter": lambda: vtk_threshold_surface(image, vtk_threshold)}
    if stripper:
        vtk_methods["vtkStripper"] = lambda: vtk_stripper(surfaces["baseline"])
    for method, function in vtk_methods.items():
        for backend in VTK_BACKENDS:
            timing, _ = time_call(_with_backend(backend, function), repeats=settings.vtk_timing_repeats, warmup=0)
            rows.append({"method": method, "smp_backend": backend, "median_s": timing.median})
    baseline = rows[0]["median_s"]
    for row in rows:
        row["ratio_to_baseline"] = row["median_s"] / baseline
    return rows


def _warm_up() -> None:
    """Compile (or load from numba's cache) every kernel on a tiny model, so no timing includes it."""
    tiny = datasets.scatter(6, density=0.5)
    surfaces = _surfaces(tiny)
    vtk_stripper(surfaces["baseline"])


# ----------------------------------------------------------------------------------------------------------------
# Data sets
# ----------------------------------------------------------------------------------------------------------------
def colin27_path() -> Path | None:
    """Where Colin 27 is on this machine, or None."""
    return next((path for path in COLIN_PATHS if path.exists()), None)


def colin27_labels(values: np.ndarray) -> np.ndarray:
    """The atlas-like label volume (uint8, labels 0-3) made from Colin 27's T1 values; see :data:`LABEL_EDGES`."""
    return np.digitize(ndimage.median_filter(values, size=3), LABEL_EDGES).astype(np.uint8)


def _real_volumes(thresholds) -> list[tuple[str, np.ndarray, float]]:
    """``(name, values, threshold)`` of the real data sets; empty when Colin 27 is not on this machine."""
    path = colin27_path()
    if path is None:
        return []
    values = load_volume(path).array
    volumes = [(f"colin27 T>={t}", values, float(t)) for t in thresholds]
    volumes.append(("colin27 labels>0", colin27_labels(values), 1.0))
    return volumes


# ----------------------------------------------------------------------------------------------------------------
# Plots
# ----------------------------------------------------------------------------------------------------------------
_STYLE = {
    "baseline": ("Def (baseline)", "C0", "o"),
    "tower": ("Tow (tower)", "C1", "s"),
    "hybrid": (f"Hyb (hybrid, L={HYBRID_L})", "C2", "^"),
    "vtkStripper": ("vtkStripper", "C3", "v"),
    "vtkStripper-deindexed": ("vtkStripper, de-indexed", "C3", "x"),
    "vtkThreshold+vtkDataSetSurfaceFilter": ("vtkThreshold + vtkDataSetSurfaceFilter", "C4", "D"),
}


def _mean_by(rows, key: str, value: str, family: str) -> dict[str, tuple[list[int], list[float]]]:
    """``{key value: (sizes, mean of value)}`` over the rows of one family."""
    groups: dict[str, dict[int, list[float]]] = {}
    for row in rows:
        if row["dataset"] == family and row.get(value) not in (None, ""):
            groups.setdefault(row[key], {}).setdefault(row["n"], []).append(float(row[value]))
    return {
        name: (sorted(by_n), [float(np.mean(by_n[n])) for n in sorted(by_n)]) for name, by_n in groups.items()
    }


def _plot_family(path: Path, family: str, memory, render, extraction, quick: bool) -> Path:
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    panels = (
        (axes[0], _mean_by(memory, "representation", "bytes_32", family), "bytes (vertices + 32-bit indices)"),
        (axes[1], _mean_by(render, "representation", "mean_ms", family), "ms per frame (VTK, llvmpipe)"),
    )
    for ax, series, ylabel in panels:
        for name, (sizes, values) in series.items():
            label, colour, marker = _STYLE[name]
            ax.plot(sizes, values, marker=marker, color=colour, label=label,
                    linestyle="--" if name.endswith("deindexed") else "-")
        ax.set_ylabel(ylabel)
    timed = [row for row in extraction if row["smp_backend"] in ("", "STDThread")]
    for name, (sizes, values) in _mean_by(timed, "method", "median_s", family).items():
        label, colour, marker = _STYLE[name]
        axes[2].plot(sizes, values, marker=marker, color=colour, label=label)
    axes[2].set_ylabel("extraction seconds (VTK: STDThread)")
    for ax in axes:
        ax.set_xlabel("voxels per side n")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title("memory (source 9.1)")
    axes[1].set_title("render time per frame (source 9.2)")
    axes[2].set_title("extraction time")
    fig.suptitle(f"{family}: voxel surfaces" + (" (quick run)" if quick else ""))
    return save_figure(fig, path, dpi=110)


def _bars(ax, names: list[str], series: dict[str, list[float]], ylabel: str, log: bool) -> None:
    width = 0.8 / max(1, len(series))
    x = np.arange(len(names))
    for index, (method, values) in enumerate(series.items()):
        label, colour, _ = _STYLE[method]
        ax.bar(x + index * width, values, width, label=label, color=colour,
               hatch="//" if method.endswith("deindexed") else None)
    ax.set_xticks(x + 0.4 - width / 2)
    ax.set_xticklabels(names, fontsize=8)
    ax.set_ylabel(ylabel)
    if log:
        ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", which="both", alpha=0.3)


def _plot_real(path: Path, memory, extraction) -> Path:
    plt = pyplot()
    names = list(dict.fromkeys(row["dataset"] for row in memory))

    def series(rows, key: str, value: str) -> dict[str, list[float]]:
        methods = list(dict.fromkeys(row[key] for row in rows))
        lookup = {(row["dataset"], row[key]): float(row[value]) for row in rows}
        return {method: [lookup.get((name, method), 0.0) for name in names] for method in methods}

    fig, axes = plt.subplots(1, 2, figsize=(14, 4.6))
    _bars(axes[0], names, series(memory, "representation", "bytes_32"), "bytes (vertices + 32-bit indices)", False)
    timed = [row for row in extraction if row["smp_backend"] in ("", "STDThread")]
    _bars(axes[1], names, series(timed, "method", "median_s"), "extraction seconds (VTK: STDThread)", True)
    fig.suptitle("Colin 27 (181 x 217 x 181, 1 mm) and its label volume")
    return save_figure(fig, path, dpi=110)


# ----------------------------------------------------------------------------------------------------------------
# Runner
# ----------------------------------------------------------------------------------------------------------------
@dataclass
class _Results:
    memory: list[dict[str, Any]] = field(default_factory=list)
    render: list[dict[str, Any]] = field(default_factory=list)
    extraction: list[dict[str, Any]] = field(default_factory=list)
    skipped: list[dict[str, Any]] = field(default_factory=list)

    def add(self, table: str, row: dict[str, Any], measured: list[dict[str, Any]]) -> None:
        getattr(self, table).extend({**row, **entry} for entry in measured)


def _measure_model(
    results: _Results,
    row: dict[str, Any],
    volume,
    threshold,
    surfaces: dict[str, Any],
    settings: Settings,
    timer: _FrameTimer | None,
    frames: int,
    *,
    timed: bool,
    stripper: bool,
) -> float:
    """Record one model's memory, extraction times (if ``timed``) and frame times (if a ``timer`` is given).

    ``volume`` and ``threshold`` are what the extraction timings start from (a mask and None, or scalars and T);
    ``stripper`` includes vtkStripper. Returns the slowest representation's mean ms per frame (0 if not rendered).
    """
    results.add("memory", row, _memory_rows(surfaces, stripper))
    if timed:
        results.add("extraction", row, _extraction_rows(volume, threshold, surfaces, settings, stripper))
    if timer is None:
        return 0.0
    rendered = _render_rows(timer, surfaces, frames)
    results.add("render", row, rendered)
    return max(entry["mean_ms"] for entry in rendered)


def _measure_family(results: _Results, family: str, settings: Settings, timer: _FrameTimer,
                    progress: ProgressCallback) -> None:
    """Every size of one family; stops rendering past :data:`RENDER_LIMIT_MS` and sizing past :data:`MAX_FACES`."""
    rendering = True
    for index, n in enumerate(settings.sizes):
        point = {"dataset": family, "n": n, "shape": f"{n}x{n}x{n}"}
        slowest_ms = 0.0
        for model in range(1 if family == "worst-case" else settings.memory_models):
            mask = datasets.family(family, n, seed=model)
            surfaces = _surfaces(mask)
            if surfaces is None:
                reason = f"more than {MAX_FACES} faces; larger sizes of this family skipped too"
                results.skipped.append({**point, "model": model, "reason": reason})
                return
            faces = surfaces["baseline"].n_faces
            frame_ms = _measure_model(
                results,
                {**point, "model": model, "faces": faces},
                mask,
                None,
                surfaces,
                settings,
                timer if rendering and model < settings.render_models else None,
                settings.frames,
                timed=model == 0,
                stripper=model < settings.stripper_models and faces <= STRIPPER_MAX_FACES,
            )
            slowest_ms = max(slowest_ms, frame_ms)
            del surfaces
        if rendering and slowest_ms > RENDER_LIMIT_MS:
            rendering = False
            results.skipped.append({**point, "reason": f"larger sizes not rendered: {slowest_ms:.0f} ms per frame"})
        report(progress, (index + 1) / len(settings.sizes))


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Run the experiments; write CSVs, one PNG per family, one for the real data and a JSON. Returns the paths."""
    configure_vtk()
    settings = QUICK if quick else FULL
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _warm_up()

    results = _Results()
    real = _real_volumes(settings.colin_thresholds)
    steps = len(datasets.FAMILIES) + len(real)
    timer = _FrameTimer()
    try:
        for index, family in enumerate(datasets.FAMILIES):
            _measure_family(results, family, settings, timer, scaled(progress, index / steps, (index + 1) / steps))
        for index, (name, values, threshold) in enumerate(real, start=len(datasets.FAMILIES)):
            surfaces = _surfaces(solid_mask(values, threshold))
            if surfaces is None:
                results.skipped.append({"dataset": name, "reason": f"more than {MAX_FACES} faces"})
                continue
            faces = surfaces["baseline"].n_faces
            row = {"dataset": name, "n": "", "shape": "x".join(map(str, values.shape)), "model": 0, "faces": faces}
            _measure_model(
                results,
                row,
                values,
                threshold,
                surfaces,
                settings,
                timer,
                settings.real_frames,
                timed=True,
                stripper=faces <= STRIPPER_MAX_FACES,
            )
            del surfaces
            report(progress, (index + 1) / steps)
    finally:
        timer.close()

    paths = [
        write_csv(out / "voxel_surfaces_memory.csv", results.memory),
        write_csv(out / "voxel_surfaces_render.csv", results.render),
        write_csv(out / "voxel_surfaces_extraction.csv", results.extraction),
    ]
    for family in datasets.FAMILIES:
        png = out / f"voxel_surfaces_{family}.png"
        paths.append(_plot_family(png, family, results.memory, results.render, results.extraction, quick))
    real_memory = [row for row in results.memory if row["n"] == ""]
    if real_memory:
        real_extraction = [row for row in results.extraction if row["n"] == ""]
        paths.append(_plot_real(out / "voxel_surfaces_real.png", real_memory, real_extraction))
    paths.append(
        write_json(
            out / "voxel_surfaces.json",
            {
                "benchmark": "voxel-surfaces",
                "quick": quick,
                "machine": machine_info(),
                "settings": asdict(settings),
                "limits": {
                    "render_limit_ms": RENDER_LIMIT_MS,
                    "max_faces": MAX_FACES,
                    "stripper_max_faces": STRIPPER_MAX_FACES,
                    "window_size": WINDOW_SIZE,
                    "hybrid_max_strip_vertices": HYBRID_L,
                },
                "real_data": {
                    "colin27": str(colin27_path()) if colin27_path() else None,
                    "thresholds": settings.colin_thresholds,
                    "labels": f"median filter 3x3x3, np.digitize at {LABEL_EDGES}, solid = label > 0",
                },
                "skipped": results.skipped,
            },
        )
    )
    return paths
