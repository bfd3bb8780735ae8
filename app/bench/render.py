"""Direct volume rendering on a fly-around of the CT head phantom: frame times, set-up and image agreement.

Source 001 compared its renderers by flying around a CT skull and recording every frame's time, then reported the
mean frame time and frame rate, the frame-time-weighted mean ``sum(t^2) / sum(t)`` (each frame weighted by how
long it stays on screen, so stutter counts) and, where a method needs one, the one-off set-up time. The same
experiment here, on the CT sample (the FORBILD head, 512 x 512 x 176, 0.547 x 0.547 x 1.5 mm, int16 HU) with the
``ct-bone`` preset at 512 x 512 pixels and half the smallest spacing as sample distance:

- The camera orbits 360 degrees around the head in ``FRAMES`` steps while its elevation wobbles by
  +-``WOBBLE_DEGREES`` (two periods per turn).
- Renderers: ``vtkGPUVolumeRayCastMapper`` (``vtk-gpu``) and ``vtkFixedPointVolumeRayCastMapper`` (``vtk-cpu``),
  each unshaded and shaded, through :func:`app.bench.common.vtk_mapper_scene` (the props every view uses,
  off-screen), and ours as listed in :data:`SOFTWARE_RENDERERS`:
  :class:`algorithms.rendering.raymarch.RaymarchRenderer` with each lighting model (``emission``, ``phong`` with
  the preset's material, ``scatter``) and :class:`algorithms.rendering.texture_slicing.SlicingRenderer`
  (view-aligned unshaded and shaded, axis-aligned), each emission/Phong/slicing variant without and with jitter
  (``-jittered``: the per-pixel sample offset that the modes use by default, issue 17), plus any entries of
  :data:`EXTRA_RENDERERS`. VTK's volume mappers are not built on vtkSMPTools (the fixed-point mapper runs its own
  threads), so VTK's SMP back end does not apply; it is STDThread as in the application.
- Per renderer: median, mean, weighted mean and 95th percentile frame time, frame rate, set-up time (construction
  plus the first frame), the numba compilation (or cache load) apart, the ratio of the median to ``vtk-cpu``'s in
  the same run, and the foreground PSNR/SSIM of the start frame against ``vtk-gpu`` (shaded modes - Phong, shaded
  slicing - against the shaded ``vtk-gpu``) and against ``vtk-cpu`` (shaded: the shaded ``vtk-cpu``); for jittered
  renderers also the PSNR of the mean of ``PASSES`` jitter passes of the start frame (what a window shows once the
  camera rests with ``--passes``). Scatter is timed but not compared: VTK has no single-scattering light model.
- Ablation of the accelerations of ``raymarch --lighting emission``: early ray termination and empty-space skipping
  both on, each off, both off (frame times, samples per ray, and the largest change of the start frame).

Frame times are wall-clock seconds of one ``render`` call (ours, one jitter pass) or one
``vtkRenderWindow.Render`` plus ``WaitForCompletion`` (VTK). Every pose is rendered by every renderer in turn, so a
change of machine load during the run affects all of them alike. Nothing is asserted; issue 17's performance point
(``raymarch-emission``'s median at most ``vtk-cpu``'s, at >= 40 dB against it) is read off ``render_summary.csv``
(``ratio_to_vtk_cpu``, ``psnr_foreground_db_vs_vtk_cpu``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from algorithms.common.progress import ProgressCallback, report
from algorithms.common.camera import Camera
from algorithms.common.render_result import RenderResult
from algorithms.compare.image_metrics import compare_images, difference_heatmap
from algorithms.rendering.raymarch import LIGHTING_MODELS, RaymarchRenderer
from algorithms.rendering.texture_slicing import SlicingRenderer
from algorithms.common.transfer import TransferTable

from ..pipeline import FrameTimes, camera_in_frame, default_camera
from ..pipeline.props import default_sample_distance
from ..transfer import transfer_function_for
from ..vtk_setup import configure_vtk
from . import slicing
from .common import ct_volume, machine_info, pyplot, save_figure, vtk_mapper_scene, write_csv, write_json

PRESET = "ct-bone"
SIZE, QUICK_SIZE = 512, 256
FRAMES, QUICK_FRAMES = 36, 6
WOBBLE_DEGREES = 20.0

#: Our renderers on the fly-around: name -> (renderer, options). Ray marching samples every ``sample_distance``;
#: texture slicing uses its own default of one slice per smallest voxel spacing along the view (issue 7). Phong and
#: ``shading`` get the preset's material and are compared with the shaded VTK mappers.
SOFTWARE_RENDERERS: dict[str, tuple[str, dict[str, Any]]] = {
    "raymarch-emission": ("raymarch", {"lighting": "emission"}),
    "raymarch-emission-jittered": ("raymarch", {"lighting": "emission", "jitter": True}),
    "raymarch-phong": ("raymarch", {"lighting": "phong"}),
    "raymarch-phong-jittered": ("raymarch", {"lighting": "phong", "jitter": True}),
    "raymarch-scatter": ("raymarch", {"lighting": "scatter", "jitter": True}),
    "slicing": ("slicing", {}),
    "slicing-jittered": ("slicing", {"jitter": True}),
    "slicing-shaded": ("slicing", {"shading": True}),
    "slicing-shaded-jittered": ("slicing", {"shading": True, "jitter": True}),
    "slicing-axis": ("slicing", {"mode": "axis"}),
}
#: Jitter passes averaged for the ``psnr_foreground_db_passes`` column of jittered renderers.
PASSES = 8

#: Extension point: more software renderers for the same fly-around, as ``(name, factory)``. ``factory(volume_array,
#: spacing, table, *, sample_distance)`` builds a renderer with the shared contract (``render(camera, width,
#: height)`` returning an :class:`algorithms.common.render_result.RenderResult`, camera in the volume frame); its
#: start frame is compared with the unshaded ``vtk-gpu``.
EXTRA_RENDERERS: list[tuple[str, Callable[..., Any]]] = []

#: Ablation settings of raymarch-emission: name -> (early termination threshold or None, empty-space skipping).
ABLATIONS = {
    "both on": (0.99, True),
    "early termination off": (None, True),
    "empty-space skipping off": (0.99, False),
    "both off": (None, False),
}


def fly_around(volume, frames: int) -> list[Camera]:
    """World cameras of the fly-around: a full azimuth turn with the elevation wobbling by +-WOBBLE_DEGREES."""
    cameras = []
    for index in range(frames):
        turn = index / frames
        elevation = WOBBLE_DEGREES * math.sin(4.0 * math.pi * turn)
        cameras.append(default_camera(volume, azimuth=360.0 * turn, elevation=elevation))
    return cameras


def _numba_warmup(table: TransferTable) -> float:
    """Seconds to compile (first run) or load from numba's cache (later runs) every kernel of the ray marcher."""
    start = time.perf_counter()
    tiny = np.zeros((4, 4, 4), dtype=np.float32)
    camera = Camera(position=(1.5, 1.5, 20.0), focal_point=(1.5, 1.5, 1.5), view_up=(0.0, 1.0, 0.0))
    for lighting in LIGHTING_MODELS:
        RaymarchRenderer(tiny, (1.0, 1.0, 1.0), table, lighting=lighting).render(camera, 4, 4)
    return time.perf_counter() - start


def _shaded(options: dict[str, Any]) -> bool:
    return options.get("lighting") == "phong" or bool(options.get("shading"))


@dataclass
class _Runner:
    """One renderer on the fly-around: its set-up, its start frame, and a frame function timed pose by pose."""

    name: str
    setup_seconds: float
    start: np.ndarray
    render: Callable[[int], dict[str, float]]
    close: Callable[[], None] = lambda: None
    #: The mean of ``PASSES`` jitter passes of the start frame (jittered renderers only).
    accumulated: np.ndarray | None = None
    frames: list[float] = field(default_factory=list)
    rows: list[dict[str, Any]] = field(default_factory=list)

    def frame(self, index: int) -> None:
        begin = time.perf_counter()
        stats = self.render(index)
        self.frames.append(time.perf_counter() - begin)
        self.rows.append({"renderer": self.name, "frame": index, "seconds": self.frames[-1],
                          **{key: value for key, value in stats.items() if key != "seconds"}})

    @property
    def times(self) -> FrameTimes:
        return FrameTimes(self.setup_seconds, self.frames)


def _software_runner(name: str, build: Callable[[], Any], cameras: list[Camera], size: int) -> _Runner:
    """Set-up: construction plus the first frame at the start pose; frames: ``render(camera, size, size)``. A
    jittered renderer's start frame is also accumulated over ``PASSES`` passes (outside the timing)."""
    start = time.perf_counter()
    renderer = build()
    first = renderer.render(cameras[0], size, size)
    setup = time.perf_counter() - start
    accumulated = None
    if getattr(renderer, "jitter", False):
        rgba = [first.rgba] + [renderer.render(cameras[0], size, size, pass_index=p).rgba for p in range(1, PASSES)]
        accumulated = RenderResult(np.mean(rgba, axis=0)).to_uint8()
    return _Runner(name, setup, first.to_uint8(), lambda index: renderer.render(cameras[index], size, size).stats,
                   accumulated=accumulated)


def _vtk_runner(name: str, volume, function, mapper: str, shading: bool, world_cameras: list[Camera], size: int,
                step: float) -> _Runner:
    """Set-up: the prop, the first render and its read-back; frames: ``Render`` plus ``WaitForCompletion``."""
    start = time.perf_counter()
    scene = vtk_mapper_scene(volume, function, mapper, size, sample_distance=step, shading=shading,
                             camera=world_cameras[0])
    scene.render()
    first = scene.capture()
    setup = time.perf_counter() - start

    def render(index: int) -> dict[str, float]:
        scene.set_camera(world_cameras[index])
        scene.render()
        return {}

    return _Runner(name, setup, first, render, scene.close)


def _plot_frame_times(path: Path, runners: list[_Runner], frames: int) -> Path:
    plt = pyplot()
    figure, axis = plt.subplots(figsize=(8, 4.5))
    azimuths = 360.0 * np.arange(frames) / frames
    for runner in runners:
        style = "--" if runner.name.startswith("vtk") else "-"
        axis.plot(azimuths, runner.frames, style, label=runner.name)
    axis.set_yscale("log")
    axis.set_xlabel("camera azimuth (degrees) along the fly-around")
    axis.set_ylabel("frame time (s)")
    axis.set_title("Frame time per frame, CT head phantom, ct-bone")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=8, ncol=2)
    return save_figure(figure, path)


def _plot_medians(path: Path, summary: list[dict[str, Any]], ablation: list[dict[str, Any]]) -> Path:
    plt = pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5), gridspec_kw={"width_ratios": [3, 2]})
    names = [row["renderer"] for row in summary]
    colours = ["0.55" if name.startswith("vtk") else "tab:blue" for name in names]
    left.bar(names, [row["median_frame_seconds"] for row in summary], color=colours)
    left.set_ylabel("median frame time (s)")
    left.set_title("Renderers (grey: VTK)")
    left.tick_params(axis="x", labelrotation=35, labelsize=8)
    right.bar([row["setting"] for row in ablation], [row["median_frame_seconds"] for row in ablation],
              color="tab:orange")
    right.set_ylabel("median frame time (s)")
    right.set_title("raymarch-emission: accelerations")
    right.tick_params(axis="x", labelrotation=35, labelsize=8)
    for axis in (left, right):
        axis.set_yscale("log")
        axis.grid(True, axis="y", which="both", alpha=0.3)
    return save_figure(figure, path)


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Run the fly-around benchmark and write CSVs, plots, example PNGs and a JSON summary; returns the files.

    ``quick`` renders ``QUICK_FRAMES`` frames at ``QUICK_SIZE`` pixels of the phantom on the quick grid: for checking that
    the benchmark runs, not for numbers.
    """
    configure_vtk()
    plt = pyplot()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    size, frames = (QUICK_SIZE, QUICK_FRAMES) if quick else (SIZE, FRAMES)
    volume = ct_volume(quick)
    function = transfer_function_for(volume, PRESET, shading=False)
    shaded_function = transfer_function_for(volume, PRESET, shading=True)
    material = shaded_function.shading
    table = function.to_table(volume.value_range)
    step = default_sample_distance(volume)
    world_cameras = fly_around(volume, frames)
    cameras = [camera_in_frame(camera, volume.local_to_world) for camera in world_cameras]
    compile_seconds = _numba_warmup(table)

    def raymarcher(**options):
        return lambda: RaymarchRenderer(volume.array, volume.spacing, table, sample_distance=step, **options)

    phong = {"ambient": material.ambient, "diffuse": material.diffuse, "specular": material.specular,
             "specular_power": material.specular_power}
    kinds = {"raymarch": lambda options: RaymarchRenderer(volume.array, volume.spacing, table, sample_distance=step,
                                                          **options),
             "slicing": lambda options: SlicingRenderer(volume.array, volume.spacing, table, **options)}
    software = [(name, lambda kind=kind, options=options: kinds[kind](
        {**options, **(phong if _shaded(options) else {})})) for name, (kind, options) in SOFTWARE_RENDERERS.items()]
    software += [(name, lambda factory=factory: factory(volume.array, volume.spacing, table, sample_distance=step))
                 for name, factory in EXTRA_RENDERERS]
    # The reference of each renderer's start frame: the shaded vtk-gpu (vtk-cpu) for shaded modes, else the
    # unshaded one. VTK has no single-scattering model like source 001's (its shadows differ by design), so scatter
    # is timed but not compared ("none": PSNR and SSIM are NaN).
    references = {"vtk-cpu-shaded": "vtk-gpu-shaded", "vtk-gpu-shaded": "vtk-gpu-shaded", "raymarch-scatter": "none"}
    references |= {name: "vtk-gpu-shaded" for name, (_, options) in SOFTWARE_RENDERERS.items() if _shaded(options)}

    runners: list[_Runner] = []
    ablations: dict[str, _Runner] = {}
    try:
        for name, mapper, shading in (("vtk-gpu", "gpu", False), ("vtk-cpu", "cpu", False),
                                      ("vtk-gpu-shaded", "gpu", True), ("vtk-cpu-shaded", "cpu", True)):
            runners.append(_vtk_runner(name, volume, shaded_function if shading else function, mapper, shading,
                                       world_cameras, size, step))
        runners += [_software_runner(name, build, cameras, size) for name, build in software]
        for setting, (termination, skipping) in ABLATIONS.items():
            build = raymarcher(early_termination=termination, empty_space_skipping=skipping)
            ablations[setting] = _software_runner(f"raymarch-emission ({setting})", build, cameras, size)
        report(progress, 0.1)
        # Pose by pose, every renderer in turn: a change of machine load during the run affects them all alike.
        for index in range(frames):
            for runner in runners + list(ablations.values()):
                runner.frame(index)
            report(progress, 0.1 + 0.7 * (index + 1) / frames)
    finally:
        for runner in runners:
            runner.close()

    by_name = {runner.name: runner for runner in runners}
    cpu_median = by_name["vtk-cpu"].times.summary()["frame_seconds"]
    summary = []
    for runner in runners:
        timing = runner.times.summary()
        reference = references.get(runner.name, "vtk-gpu")
        comparison = compare_images(by_name[reference].start, runner.start) if reference in by_name else None
        cpu_reference = reference.replace("vtk-gpu", "vtk-cpu")
        against_cpu = (compare_images(by_name[cpu_reference].start, runner.start).psnr_foreground
                       if cpu_reference in by_name else math.nan)
        accumulated = (compare_images(by_name[reference].start, runner.accumulated).psnr_foreground
                       if runner.accumulated is not None and reference in by_name else math.nan)
        summary.append({
            "renderer": runner.name,
            "median_frame_seconds": timing["frame_seconds"],
            "mean_frame_seconds": timing["mean_frame_seconds"],
            "frames_per_second": 1.0 / timing["mean_frame_seconds"],
            "weighted_mean_frame_seconds": timing["weighted_mean_frame_seconds"],
            "p95_frame_seconds": timing["p95_frame_seconds"],
            "setup_seconds": timing["setup_seconds"],
            "compile_seconds": compile_seconds if runner.name.startswith("raymarch") else math.nan,
            "ratio_to_vtk_cpu": timing["frame_seconds"] / cpu_median,
            "reference": reference,
            "psnr_foreground_db": comparison.psnr_foreground if comparison else math.nan,
            "ssim": comparison.ssim if comparison else math.nan,
            "jitter": runner.accumulated is not None,
            "psnr_foreground_db_passes": accumulated,
            "reference_cpu": cpu_reference if cpu_reference in by_name else "none",
            "psnr_foreground_db_vs_vtk_cpu": against_cpu,
            "frames": timing["frames"],
        })
    both_off = ablations["both off"]
    both_off_median = both_off.times.summary()["frame_seconds"]
    ablation = []
    for setting, runner in ablations.items():
        median = runner.times.summary()["frame_seconds"]
        ablation.append({
            "setting": setting,
            "early_termination": ABLATIONS[setting][0] is not None,
            "empty_space_skipping": ABLATIONS[setting][1],
            "median_frame_seconds": median,
            "speed_up_over_both_off": both_off_median / median,
            "samples_per_ray": float(np.mean([row["samples_per_ray"] for row in runner.rows])),
            "skipped_fraction": float(np.mean([row["skipped_fraction"] for row in runner.rows])),
            "early_terminated": float(np.mean([row["early_terminated"] for row in runner.rows])),
            "max_start_frame_difference": float(
                np.abs(runner.start.astype(int) - both_off.start.astype(int)).max() / 255.0),
        })

    written = [
        write_csv(out_dir / "render_summary.csv", summary),
        write_csv(out_dir / "render_ablation.csv", ablation),
        write_csv(out_dir / "render_frames.csv",
                  [row for runner in runners + list(ablations.values()) for row in runner.rows]),
        _plot_frame_times(out_dir / "render_frame_times.png", runners, frames),
        _plot_medians(out_dir / "render_medians.png", summary, ablation),
    ]
    for runner in runners:
        path = out_dir / f"render_start_{runner.name}.png"
        plt.imsave(path, runner.start)
        written.append(path)
    heatmap = out_dir / "render_difference_raymarch-emission_vs_vtk-gpu.png"
    plt.imsave(heatmap, difference_heatmap(by_name["vtk-gpu"].start, by_name["raymarch-emission"].start))
    written.append(heatmap)
    written.append(write_json(out_dir / "render.json", {
        "benchmark": "render",
        "machine": machine_info(),
        "volume": {"name": "sample ct (FORBILD head)", "shape": list(volume.array.shape), "spacing_mm": list(volume.spacing)},
        "preset": PRESET,
        "image_size": [size, size],
        "frames": frames,
        "sample_distance_mm": step,
        "jitter_passes_accumulated": PASSES,
        "quick": quick,
        "numba_compile_or_cache_load_seconds": compile_seconds,
        "summary": summary,
        "ablation": ablation,
        "notes": [
            "Frame times are wall-clock seconds; set-up is construction plus the first frame at the start pose.",
            "Every pose is rendered by every renderer in turn, so changes of machine load affect all alike.",
            "VTK's volume mappers do not use vtkSMPTools; the fixed-point mapper threads on its own.",
            "PSNR is over the foreground of the start frame; shaded modes are compared with vtk-gpu-shaded "
            "(and vtk-cpu-shaded); scatter is not compared (VTK has no such light model).",
            "Jittered renderers are timed one pass per frame; psnr_foreground_db_passes is the mean of "
            f"{PASSES} jitter passes of the start frame.",
            "Without a GPU, vtk-gpu runs on Mesa's llvmpipe software rasteriser.",
        ],
    }))
    # Texture slicing against slice count, its 8-bit error and the axis-aligned switching artefact (issue 7).
    written += slicing.run(out_dir / "slicing", quick=quick,
                           progress=None if progress is None else (lambda f: progress(0.8 + 0.2 * f)))
    report(progress, 1.0)
    return written


__all__ = ["ABLATIONS", "EXTRA_RENDERERS", "PASSES", "SOFTWARE_RENDERERS", "fly_around", "run"]
