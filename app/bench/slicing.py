"""Texture slicing against VTK's ray casters: frame time and image quality by slice count, 8-bit compositing,
and the axis-aligned stack switch.

Source 001 (technique 3) renders a CT skull with view-aligned texture slices and finds them fast for their
quality; source 002 (2.4.3) warns that compositing in an 8-bit framebuffer loses up to 40 % after a hundred slices,
and that switching between axis-aligned stacks flickers. Measured here, on the CT sample (the FORBILD head,
512 x 512 x 176, 0.547 x 0.547 x 1.5 mm) at 512 x 512 pixels with the ``ct-bone`` preset and no shading:

1. Frame time against the number of view-aligned slices (64, 128, 256, 512 and the default of one slice per smallest
   spacing) for the rasterising path (:class:`algorithms.rendering.texture_slicing.SliceStackProp` in VTK's OpenGL
   renderer: slice geometry and textures on the CPU, then the draw, reported apart), the float compositing path and its
   8-bit emulation (:class:`algorithms.rendering.texture_slicing.SlicingRenderer`), next to
   ``vtkGPUVolumeRayCastMapper`` and ``vtkFixedPointVolumeRayCastMapper`` (medians over repeats, ratios in the same
   run). The volume mappers are not built on vtkSMPTools, so VTK's SMP back end does not apply to them (the fixed-point
   mapper runs its own threads).
2. Foreground PSNR (and SSIM) of each path against ``vtk-gpu`` at its default sample distance (half the smallest
   spacing), as the slices increase; also with ``ct-soft-tissue``, whose low opacity per slice is where source
   002's 8-bit error shows (``ct-bone`` turns opaque within a few slices).
3. The axis-aligned switch: the camera turns in quarter-degree steps through the 45 degree azimuth where the
   stack along y gives way to the stack along x; the difference between consecutive frames of the axis-aligned
   path jumps at the switch (the two stacks sample the volume at different points, source 002's flicker), while
   the view-aligned path and VTK change smoothly.

The rasterising path runs on whatever OpenGL the machine has; with Mesa's llvmpipe (no GPU) the "draw" is a
software rasteriser too, so its time says little about a graphics card.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.compare.image_metrics import compare_images, difference_heatmap, difference_image, psnr_foreground
from algorithms.rendering.texture_slicing import SliceStackProp, SlicingRenderer

from ..datasets import ct_head_phantom
from ..pipeline import OffscreenScene, camera_in_frame, default_camera
from ..pipeline.offscreen import render_vtk_volume
from ..pipeline.props import default_sample_distance
from ..transfer import transfer_function_for
from .common import (Timing, ct_volume, machine_info, pyplot, save_figure, time_call, vtk_mapper_scene, write_csv,
                     write_json)

PRESET = "ct-bone"
#: A preset of low opacity per slice, for the 8-bit compositing error (image quality only).
FAINT_PRESET = "ct-soft-tissue"
SLICE_COUNTS = (64, 128, 256, 512)
QUICK_SLICE_COUNTS = (32, 64, 128)
#: Camera of the timing and quality runs: azimuth and elevation (degrees) from the anterior view.
AZIMUTH, ELEVATION = 30.0, 10.0
#: Azimuths of the stack-switch sequence (degrees); the y stack gives way to the x stack just after 45. Steps of
#: a quarter degree keep the change that the turn itself causes below the jump of the switch.
SWITCH_AZIMUTHS = np.arange(43.0, 47.01, 0.25)
QUICK_SWITCH_AZIMUTHS = np.arange(44.0, 46.01, 0.5)
#: Differences shown as full yellow in the heat maps against vtk-gpu and of the switch (0-1 units).
FRAME_HEATMAP_VMAX = 0.25
SWITCH_HEATMAP_VMAX = 0.1


def _time_vtk(volume, function, size: int, world_camera, repeats: int) -> tuple[dict[str, float], np.ndarray]:
    """Median frame seconds of vtk-gpu and vtk-cpu (set-up excluded), and the vtk-gpu frame."""
    seconds = {}
    reference = None
    for mapper in ("gpu", "cpu"):
        scene = vtk_mapper_scene(volume, function, mapper, size, camera=world_camera)
        try:
            timing, _ = time_call(scene.render, repeats=repeats, warmup=1)
            seconds[mapper] = timing.median
            if mapper == "gpu":
                reference = scene.capture()
        finally:
            scene.close()
    return seconds, reference


def _gl_frame(stack: SliceStackProp, scene: OffscreenScene, camera, size: int, parts: dict[str, list[float]]):
    """One frame of the rasterising path: rebuild slices and textures, then draw; the two times are recorded."""
    stats = stack.update(camera, size, size)
    parts["update"].append(stats["seconds"])
    parts["draw"].append(scene.render())
    return stats


def _slice_count_runs(volume, table, world_camera, counts, size, reference, *, preset: str, repeats: int,
                      warmup: int, progress: ProgressCallback):
    """Frame times and image quality against ``reference`` of the GL, float and uint8 paths for every slice count."""
    camera = camera_in_frame(world_camera, volume.local_to_world)
    time_rows, quality_rows, frames = [], [], {}
    for step, (label, count) in enumerate(counts):
        for precision in ("float", "uint8"):
            renderer = SlicingRenderer(volume.array, volume.spacing, table, slices=count, precision=precision)
            timing, result = time_call(lambda: renderer.render(camera, size, size), repeats=repeats, warmup=warmup)
            frames[(label, precision)] = result.to_uint8()
            time_rows.append({"path": precision, "slices": count, "label": label, "frame_seconds": timing.median,
                              "cpu_seconds": timing.median, "draw_seconds": 0.0, **result.stats})
        renderer = SlicingRenderer(volume.array, volume.spacing, table, slices=count)
        scene = OffscreenScene((size, size))
        try:
            stack = SliceStackProp(renderer, user_matrix=volume.local_to_world)
            stack.attach(scene.renderer)
            scene.set_camera(world_camera)
            parts = {"update": [], "draw": []}
            timing, stats = time_call(lambda: _gl_frame(stack, scene, camera, size, parts), repeats=repeats,
                                      warmup=warmup)
            frames[(label, "gl")] = scene.capture()
        finally:
            scene.close()
        time_rows.append({"path": "gl", "slices": count, "label": label, "frame_seconds": timing.median,
                          "cpu_seconds": Timing(parts["update"][warmup:]).median,
                          "draw_seconds": Timing(parts["draw"][warmup:]).median, **stats})
        for path in ("gl", "float", "uint8"):
            quality_rows.append({"preset": preset, "path": path, "slices": count, "label": label,
                                 **compare_images(reference, frames[(label, path)]).as_dict()})
        report(progress, (step + 1) / len(counts))
    return time_rows, quality_rows, frames


def _switch_sequence(volume, function, table, size, azimuths, progress: ProgressCallback):
    """Float-path frames of the axis-aligned and view-aligned stacks and vtk-gpu frames while the camera turns."""
    axis_renderer = SlicingRenderer(volume.array, volume.spacing, table, mode="axis")
    view_renderer = SlicingRenderer(volume.array, volume.spacing, table)
    first = default_camera(volume, azimuth=float(azimuths[0]), elevation=0.0)
    scene = vtk_mapper_scene(volume, function, "gpu", size, camera=first)
    frames = {"axis": [], "view": [], "vtk-gpu": []}
    axes = []
    try:
        for index, azimuth in enumerate(azimuths):
            world_camera = default_camera(volume, azimuth=float(azimuth), elevation=0.0)
            camera = camera_in_frame(world_camera, volume.local_to_world)
            result = axis_renderer.render(camera, size, size)
            axes.append(int(result.stats["axis"]))
            frames["axis"].append(result.to_uint8())
            frames["view"].append(view_renderer.render(camera, size, size).to_uint8())
            scene.set_camera(world_camera)
            scene.render()
            frames["vtk-gpu"].append(scene.capture())
            report(progress, (index + 1) / len(azimuths))
    finally:
        scene.close()
    rows = []
    for index, azimuth in enumerate(azimuths):
        row = {"azimuth_degrees": float(azimuth), "stack_axis": "xyz"[axes[index]]}
        for path in ("axis", "view"):
            row[f"{path}_psnr_foreground_db"] = psnr_foreground(frames["vtk-gpu"][index], frames[path][index])
        for path in ("axis", "view", "vtk-gpu"):
            if index:
                change = difference_image(frames[path][index - 1], frames[path][index])
                row[f"{path}_step_rmse"] = float(np.sqrt(np.mean(change.astype(np.float64) ** 2)))
            else:
                row[f"{path}_step_rmse"] = float("nan")
        rows.append(row)
    return rows, frames, axes


def _plot_times(path: Path, rows, vtk_seconds) -> Path:
    plt = pyplot()
    figure, axis = plt.subplots(figsize=(7, 4.5))
    styles = {"gl": ("OpenGL path (CPU slices + draw)", "o-"), "float": ("float path", "s-"),
              "uint8": ("8-bit emulation", "^--")}
    for key, (name, style) in styles.items():
        selected = sorted((r for r in rows if r["path"] == key), key=lambda r: r["slices"])
        axis.plot([r["slices"] for r in selected], [r["frame_seconds"] for r in selected], style, label=name)
        if key == "gl":
            axis.plot([r["slices"] for r in selected], [r["draw_seconds"] for r in selected], "o:",
                      label="OpenGL path: draw only")
    for mapper, linestyle in (("gpu", "-"), ("cpu", "--")):
        axis.axhline(vtk_seconds[mapper], color="k", linestyle=linestyle, label=f"vtk-{mapper}")
    axis.set_xscale("log", base=2)
    axis.set_yscale("log")
    axis.set_xlabel("view-aligned slices")
    axis.set_ylabel("frame time (s, median)")
    axis.set_title("Texture slicing: frame time by slice count")
    axis.legend(fontsize=8)
    axis.grid(True, which="both", alpha=0.3)
    return save_figure(figure, path)


def _plot_quality(path: Path, rows, default_count: int) -> Path:
    plt = pyplot()
    presets = list(dict.fromkeys(r["preset"] for r in rows))
    figure, axes = plt.subplots(1, len(presets), figsize=(6.5 * len(presets), 4.5), squeeze=False)
    for axis, preset in zip(axes[0], presets):
        for key, name, style in (("gl", "OpenGL (8-bit textures and framebuffer)", "o-"), ("float", "float", "s-"),
                                 ("uint8", "float textures, 8-bit accumulation", "^--")):
            selected = sorted((r for r in rows if r["path"] == key and r["preset"] == preset),
                              key=lambda r: r["slices"])
            axis.plot([r["slices"] for r in selected], [r["psnr_foreground"] for r in selected], style, label=name)
        axis.axvline(default_count, color="0.5", linestyle=":", label=f"default ({default_count} slices)")
        axis.set_xscale("log", base=2)
        axis.set_xlabel("view-aligned slices")
        axis.set_ylabel("foreground PSNR against vtk-gpu (dB)")
        axis.set_title(f"{preset}, no shading")
        axis.legend(fontsize=8)
        axis.grid(True, alpha=0.3)
    figure.suptitle("Texture slicing against vtk-gpu by slice count")
    return save_figure(figure, path)


def _plot_switch(path: Path, rows, switch_azimuth: float) -> Path:
    plt = pyplot()
    figure, axis = plt.subplots(figsize=(7, 4.5))
    for key, name, style in (("axis", "axis-aligned stack", "o-"), ("view", "view-aligned slices", "s-"),
                             ("vtk-gpu", "vtk-gpu", "k--")):
        axis.plot([r["azimuth_degrees"] for r in rows[1:]], [r[f"{key}_step_rmse"] for r in rows[1:]], style,
                  label=name)
    axis.axvline(switch_azimuth, color="0.5", linestyle=":", label="stack switches (y to x)")
    axis.set_xlabel("camera azimuth (degrees)")
    axis.set_ylabel("RMSE to the previous frame (0-1 units)")
    axis.set_title("Axis-aligned stack switch: change between consecutive frames")
    axis.legend(fontsize=8)
    axis.grid(True, alpha=0.3)
    return save_figure(figure, path)


def _image_grid(path: Path, columns: list[tuple[str, np.ndarray, np.ndarray | None]], title: str) -> Path:
    """Frames in the top row and, under each, a difference heat map (or nothing)."""
    plt = pyplot()
    figure, axes = plt.subplots(2, len(columns), figsize=(3.2 * len(columns), 6.6), squeeze=False)
    for index, (name, frame, heatmap) in enumerate(columns):
        axes[0, index].imshow(frame)
        axes[0, index].set_title(name, fontsize=9)
        if heatmap is not None:
            axes[1, index].imshow(heatmap)
        for row in (0, 1):
            axes[row, index].axis("off")
    figure.suptitle(title, fontsize=10)
    return save_figure(figure, path, dpi=110)


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Run the benchmark and write CSV, plots, PNGs and a JSON summary into ``out_dir``; returns the files.

    ``quick`` uses the reduced phantom (96 x 96 x 40) at 256 x 256 pixels, fewer slice counts, one repeat and a
    shorter turn: for checking that the benchmark runs, not for numbers.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    if quick:
        volume = ct_head_phantom(shape=(40, 96, 96))
        size, repeats, counts, azimuths = 256, 1, QUICK_SLICE_COUNTS, QUICK_SWITCH_AZIMUTHS
    else:
        volume = ct_volume(quick)
        size, repeats, counts, azimuths = 512, 3, SLICE_COUNTS, SWITCH_AZIMUTHS
    function = transfer_function_for(volume, PRESET, shading=False)
    table = function.to_table(volume.value_range)
    world_camera = default_camera(volume, azimuth=AZIMUTH, elevation=ELEVATION)
    camera = camera_in_frame(world_camera, volume.local_to_world)
    default_count = len(SlicingRenderer(volume.array, volume.spacing, table).slices_for(camera))
    runs = [(str(count), count) for count in counts] + [("default", default_count)]

    vtk_seconds, reference = _time_vtk(volume, function, size, world_camera, repeats)
    report(progress, 0.05)
    time_rows, quality_rows, frames = _slice_count_runs(
        volume, table, world_camera, runs, size, reference, preset=PRESET, repeats=repeats, warmup=1,
        progress=scaled(progress, 0.05, 0.6))
    for mapper in ("gpu", "cpu"):
        time_rows.append({"path": f"vtk-{mapper}", "slices": "", "label": "", "frame_seconds": vtk_seconds[mapper]})
    for row in time_rows:
        row["ratio_to_vtk_gpu"] = row["frame_seconds"] / vtk_seconds["gpu"]
        row["ratio_to_vtk_cpu"] = row["frame_seconds"] / vtk_seconds["cpu"]
    # Image quality only (one untimed frame per path) with a faint preset, where 8-bit compositing shows.
    faint = transfer_function_for(volume, FAINT_PRESET, shading=False)
    faint_reference = render_vtk_volume(volume, world_camera, faint, mapper="gpu", size=(size, size))
    _, faint_rows, _ = _slice_count_runs(
        volume, faint.to_table(volume.value_range), world_camera, runs, size, faint_reference, preset=FAINT_PRESET,
        repeats=1, warmup=0, progress=scaled(progress, 0.6, 0.8))
    quality_rows += faint_rows
    switch_rows, switch_frames, axes = _switch_sequence(volume, function, table, size, azimuths,
                                                        scaled(progress, 0.8, 0.98))

    written = [
        write_csv(out_dir / "slicing_frame_times.csv", time_rows,
                  ["path", "slices", "label", "frame_seconds", "cpu_seconds", "draw_seconds", "ratio_to_vtk_gpu",
                   "ratio_to_vtk_cpu", "texels", "texel_size_mm", "slice_distance_mm", "path_step_mm"]),
        write_csv(out_dir / "slicing_quality.csv", quality_rows),
        write_csv(out_dir / "slicing_axis_switch.csv", switch_rows),
    ]
    written.append(_plot_times(out_dir / "slicing_frame_times.png", time_rows, vtk_seconds))
    written.append(_plot_quality(out_dir / "slicing_quality.png", quality_rows, default_count))
    switch_index = next((i for i in range(1, len(axes)) if axes[i] != axes[i - 1]), None)
    switch_azimuth = float(azimuths[switch_index]) if switch_index is not None else float("nan")
    written.append(_plot_switch(out_dir / "slicing_axis_switch.png", switch_rows, switch_azimuth))

    default_frames = [("vtk-gpu", reference, None)] + [
        (f"{name} ({default_count} slices)", frames[("default", key)],
         difference_heatmap(reference, frames[("default", key)], vmax=FRAME_HEATMAP_VMAX))
        for key, name in (("float", "float"), ("uint8", "8-bit accumulation"), ("gl", "OpenGL"))
    ]
    written.append(_image_grid(out_dir / "slicing_frames.png", default_frames,
                               "Texture slicing against vtk-gpu; differences below "
                               f"(black 0, yellow >= {FRAME_HEATMAP_VMAX:g})"))
    if switch_index is not None:
        before, after = switch_index - 1, switch_index
        columns = [(f"axis-aligned, {azimuths[before]:g} deg ({'xyz'[axes[before]]} stack)",
                    switch_frames["axis"][before], None),
                   (f"axis-aligned, {azimuths[after]:g} deg ({'xyz'[axes[after]]} stack)",
                    switch_frames["axis"][after],
                    difference_heatmap(switch_frames["axis"][before], switch_frames["axis"][after],
                                       vmax=SWITCH_HEATMAP_VMAX))]
        for path in ("view", "vtk-gpu"):
            columns.append((f"{path}, {azimuths[after]:g} deg", switch_frames[path][after],
                            difference_heatmap(switch_frames[path][before], switch_frames[path][after],
                                               vmax=SWITCH_HEATMAP_VMAX)))
        written.append(_image_grid(out_dir / "slicing_axis_switch_frames.png", columns,
                                   "Change from the previous frame at the stack switch "
                                   f"(black 0, yellow >= {SWITCH_HEATMAP_VMAX:g})"))

    def rmse_at(path: str, index: int | None) -> float:
        return float(switch_rows[index][f"{path}_step_rmse"]) if index is not None else float("nan")

    def median_rmse_elsewhere(path: str) -> float:
        values = [r[f"{path}_step_rmse"] for i, r in enumerate(switch_rows[1:], start=1) if i != switch_index]
        return float(np.median(values))

    by_label = {(r["preset"], r["path"], r["label"]): r for r in quality_rows}
    summary = {
        "machine": machine_info(),
        "configuration": {
            "volume": "FORBILD head phantom", "shape_zyx": list(volume.array.shape), "spacing_mm": list(volume.spacing),
            "image_size": [size, size], "preset": PRESET, "shading": False, "azimuth_degrees": AZIMUTH,
            "elevation_degrees": ELEVATION, "repeats": repeats, "quick": quick,
            "vtk_sample_distance_mm": default_sample_distance(volume),
            "vtk_smp_backend": "not applicable: the volume mappers do not use vtkSMPTools",
            "default_slices": default_count,
        },
        "vtk_frame_seconds": vtk_seconds,
        "default_slices": {
            path: {"psnr_foreground_db": by_label[(PRESET, path, "default")]["psnr_foreground"],
                   "ssim": by_label[(PRESET, path, "default")]["ssim"],
                   "frame_seconds": next(r["frame_seconds"] for r in time_rows
                                         if r["path"] == path and r["label"] == "default")}
            for path in ("gl", "float", "uint8")
        },
        f"{FAINT_PRESET}_psnr_foreground_db": {
            label: {path: by_label[(FAINT_PRESET, path, label)]["psnr_foreground"] for path in ("gl", "float", "uint8")}
            for label, _ in runs
        },
        "axis_switch": {
            "switch_azimuth_degrees": switch_azimuth,
            "axis_step_rmse_at_switch": rmse_at("axis", switch_index),
            "axis_step_rmse_median_elsewhere": median_rmse_elsewhere("axis"),
            "view_step_rmse_at_switch": rmse_at("view", switch_index),
            "vtk_gpu_step_rmse_at_switch": rmse_at("vtk-gpu", switch_index),
        },
        "notes": [
            "frame_seconds of the gl path = slice geometry and textures on the CPU (cpu_seconds) + OpenGL draw "
            "including texture upload (draw_seconds)",
            "OpenGL here may be Mesa llvmpipe (software); see machine.platform",
        ],
        "seconds": time.perf_counter() - started,
    }
    written.append(write_json(out_dir / "slicing.json", summary))
    report(progress, 1.0)
    return written
