"""Shear-warp benchmark: source 004's tests, and the CT phantom against VTK's ray casters in the same run.

Source 004 (Tavira Rodríguez de Liébana, *Optimización del renderizado de volumen mediante la técnica
shear-warping*, 2017, chapter 6) timed its shear-warp renderer on random
volumes; the same tests here, with :class:`algorithms.rendering.shear_warp.ShearWarpRenderer` at 512 x 512 pixels:

- **Test 1 (volume size)**: random volumes of 128x128x64, 256x256x64, 256x256x128, 256x256x256 and 512x512x128
  voxels (x by y by z) with 100 % non-transparent voxels, ``VOLUMES`` random volumes each
  (:func:`app.datasets.random_volume`).
- **Test 2 (transparency)**: 256^3 random volumes with 0, 25, 50 and 75 % transparent voxels.

  Transfer function of both (stated as the source asks): grey levels, colour black at 0 to white at 255, opacity
  0 at value 0 (the transparent voxels) rising linearly to 0.3 per mm at 255, so every value above 0 is
  non-transparent. Spacing 1 mm, shading on (the source shades through its normal table), early termination at
  0.99. Each volume is seen by ``FRAMES`` parallel cameras turning around it (elevation 20 degrees); the median
  frame time per volume is reported and then averaged over the volumes of a size, as the source did.

- **CT phantom**: the CT sample (the FORBILD head, 512 x 512 x 176, 0.547 x 0.547 x 1.5 mm; quick: on 256 x 256 x
  88 voxels) with
  the ``ct-bone`` preset, unshaded, parallel projection, 512 x 512, over ``CT_FRAMES`` frames of a turning camera:
  shear-warp against ``vtkFixedPointVolumeRayCastMapper`` (``vtk-cpu``) and ``vtkGPUVolumeRayCastMapper``
  (``vtk-gpu``, Mesa's llvmpipe without a GPU) with VTK's default sample distance of our renderers (half the
  smallest spacing). Ablations: without the volume's run-length encoding (every voxel visited), without early ray
  termination (which also turns off opaque-pixel skipping), without both; shear-warp shaded (normal grid 128);
  shear-warp pre-scaled to isotropic 0.9375 mm voxels (``resample_spacing``, the default), and that with jitter
  (one post-classified sample between each pair of slices, :mod:`algorithms.rendering.shear_warp.jitter`).
  Set-up (classification, encoding; normals with shading) is reported apart from the frame times; so is the first
  frame (numba's cache load). The start frame is compared with ``vtk-gpu`` (foreground PSNR, SSIM) and a difference
  heat map is written.
- **Anisotropic CT, parallel and perspective** (issue 17): the same phantom sampled on a real CT head series' grid,
  ``ANISOTROPIC_SHAPE`` = 256 x 256 x 108 voxels of ``ANISOTROPIC_SPACING`` = 0.96 x 0.96 x 1.5 mm, ``ct-bone``,
  unshaded, 512 x 512, ``CT_FRAMES`` frames of a turning camera once with parallel and once with perspective
  projection: shear-warp at its default (resampled to the smallest spacing, source 004 section 6.3.1; perspective
  after Lacroute's factorisation) and on the volume's own grid, against ``vtk-cpu`` and ``vtk-gpu`` with the same
  projection. The issue's points: foreground PSNR against ``vtk-gpu`` >= 26 dB parallel and >= 24 dB perspective,
  median frame time <= 0.5 x ``vtk-cpu``'s (``shear_warp_anisotropic.csv``).
- **Banding**: the shaded start frame with a coarse (8) and a fine (128) normal grid side by side, and
  :func:`algorithms.compare.image_metrics.shading_banding` of a shaded sphere for several grids.

VTK's volume mappers do not use vtkSMPTools (the fixed-point mapper runs its own threads), so VTK's SMP back end
does not apply to them; it is STDThread as in the application. Frame times are wall-clock seconds of one
``render`` call (ours) or one ``vtkRenderWindow.Render`` plus ``WaitForCompletion`` (VTK). Nothing is asserted:
the issue's performance points (shear-warp's median at most half of vtk-cpu's on the CT phantom; every size of
test 1 well under a second) are read off ``shear_warp_ct.csv`` and ``shear_warp_sizes.csv``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.common.camera import Camera
from algorithms.compare.image_metrics import compare_images, difference_heatmap, shading_banding
from algorithms.rendering.shear_warp import NormalTable, ShearWarpRenderer
from algorithms.common.transfer import TransferTable

from ..datasets import ct_head_phantom, random_volume, sphere_field
from ..pipeline import FrameTimes, camera_in_frame, default_camera, turning_cameras
from ..pipeline.props import default_sample_distance
from ..transfer import transfer_function_for
from ..volume import Volume
from ..vtk_setup import configure_vtk
from .common import ct_volume, machine_info, pyplot, save_figure, time_vtk_mapper, write_csv, write_json

SIZE = 512
#: Test 1 sizes as (x, y, z) voxels, as the source lists them.
SIZES = ((128, 128, 64), (256, 256, 64), (256, 256, 128), (256, 256, 256), (512, 512, 128))
TRANSPARENT_PERCENT = (0, 25, 50, 75)
VOLUMES, QUICK_VOLUMES = 3, 1
FRAMES, QUICK_FRAMES = 6, 3
CT_FRAMES, QUICK_CT_FRAMES = 24, 4
TURN_DEGREES = 15.0
ELEVATION = 20.0
PRESET = "ct-bone"
#: The anisotropic CT: a real head series' grid (voxels z, y, x; spacing x, y, z in mm).
ANISOTROPIC_SHAPE = (108, 256, 256)
ANISOTROPIC_SPACING = (0.96, 0.96, 1.5)
#: Its variants (name -> renderer options): the default (resampled to the smallest spacing) and the own grid.
ANISOTROPIC_VARIANTS = {
    "shear-warp (default: resampled)": {},
    "shear-warp (own grid)": {"resample_spacing": None},
}
#: Normal grids of the banding comparison (cells per side of the source's grid).
BANDING_GRIDS = (8, 18, 32, 64, 128)
#: Grey levels with opacity 0 at value 0 only: the transfer function of tests 1 and 2.
RANDOM_TABLE = TransferTable.from_points([(0, 0, 0, 0), (255, 1, 1, 1)], [(0, 0), (255, 0.3)], (0, 255))
#: CT variants: name -> renderer options (``vtk-*`` rows are VTK's mappers).
#: The source's algorithm and its ablations run on the volume's own grid (``resample_spacing=None``); the
#: renderer's default resamples this anisotropic phantom to its smallest spacing (the last row).
CT_VARIANTS = {
    "shear-warp": {"resample_spacing": None},
    "shear-warp (no RLE)": {"use_rle": False, "resample_spacing": None},
    "shear-warp (no early termination)": {"early_termination": None, "resample_spacing": None},
    "shear-warp (no RLE + no early termination)": {"use_rle": False, "early_termination": None,
                                                   "resample_spacing": None},
    "shear-warp shaded": {"shading": True, "resample_spacing": None},
    "shear-warp resampled to 0.9375 mm (default)": {"resample_spacing": "auto"},
    "shear-warp resampled, jittered": {"resample_spacing": "auto", "jitter": True},
}


def _stats_means(results) -> dict[str, float]:
    keys = ("composite_seconds", "warp_seconds", "voxels_composited", "voxels_skipped_transparent",
            "pixels_skipped_opaque")
    return {key: float(np.mean([result.stats[key] for result in results])) for key in keys}


def _time_renderer(build: Callable[[], ShearWarpRenderer], cameras: list[Camera], size: int) -> dict[str, Any]:
    """Set-up, the first frame (cache load) and every frame of ``cameras`` (volume frame) of one renderer."""
    start = time.perf_counter()
    renderer = build()
    setup = time.perf_counter() - start
    begin = time.perf_counter()
    first = renderer.render(cameras[0], size, size)
    first_seconds = time.perf_counter() - begin
    results = []
    frames = []
    for camera in cameras:
        tick = time.perf_counter()
        results.append(renderer.render(camera, size, size))
        frames.append(time.perf_counter() - tick)
    return {"times": FrameTimes(setup, frames), "first_seconds": first_seconds, "start": first,
            "setup_stats": renderer.setup_stats, "stats": _stats_means(results), "spacing": renderer.spacing}


def _turning_cameras(volume: Volume, frames: int) -> list[Camera]:
    """Parallel world cameras turning around ``volume`` at ``ELEVATION`` degrees, ``TURN_DEGREES`` per frame."""
    start = default_camera(volume, elevation=ELEVATION, parallel=True)
    return turning_cameras(start, frames, TURN_DEGREES)


def _random_row(label: dict[str, Any], volume: np.ndarray, frames: int, progress: ProgressCallback) -> dict[str, Any]:
    cameras = _turning_cameras(Volume(volume), frames)  # unit spacing at the origin: world = volume frame
    run = _time_renderer(lambda: ShearWarpRenderer(volume, (1.0, 1.0, 1.0), RANDOM_TABLE, shading=True), cameras,
                         SIZE)
    timing = run["times"].summary()
    setup = run["setup_stats"]
    report(progress, 1.0)
    return {
        **label,
        "voxels": int(volume.size),
        "median_frame_seconds": timing["frame_seconds"],
        "mean_frame_seconds": timing["mean_frame_seconds"],
        "first_frame_seconds": run["first_seconds"],
        "setup_seconds": timing["setup_seconds"],
        "normal_seconds": setup["normal_seconds"],
        "classification_seconds": setup["classification_seconds"],
        "encoding_seconds": setup["encoding_seconds"],
        "raw_bytes": setup["raw_bytes"],
        "encoded_bytes_per_copy": float(np.mean([setup[f"encoded_bytes_{a}"] for a in "xyz"])),
        **run["stats"],
    }


def _averaged(rows: list[dict[str, Any]], key: str) -> list[dict[str, Any]]:
    """Mean over the random volumes of each ``key`` value (the source averaged its 3 volumes)."""
    out = []
    for value in dict.fromkeys(row[key] for row in rows):
        group = [row for row in rows if row[key] == value]
        numbers = {name: float(np.mean([row[name] for row in group])) for name in group[0]
                   if isinstance(group[0][name], (int, float)) and name not in (key, "seed")}
        out.append({key: value, "volumes": len(group), **numbers})
    return out


def _anisotropic_rows(frames: int, progress: ProgressCallback) -> tuple[list[dict[str, Any]], np.ndarray]:
    """The anisotropic CT with parallel and with perspective projection: rows per projection and renderer, and a
    montage of the start frames (rows: parallel, perspective; columns: vtk-gpu, shear-warp default)."""
    volume = ct_head_phantom(ANISOTROPIC_SHAPE, ANISOTROPIC_SPACING)
    function = transfer_function_for(volume, PRESET, shading=False)
    table = function.to_table(volume.value_range)
    step = default_sample_distance(volume)
    rows, montage = [], []
    projections = ("parallel", "perspective")
    for index, projection in enumerate(projections):
        start = default_camera(volume, elevation=ELEVATION, parallel=projection == "parallel")
        world_cameras = turning_cameras(start, frames, TURN_DEGREES)
        cameras = [camera_in_frame(camera, volume.local_to_world) for camera in world_cameras]
        runs: dict[str, dict[str, Any]] = {}
        for name, mapper in (("vtk-cpu", "cpu"), ("vtk-gpu", "gpu")):
            runs[name] = time_vtk_mapper(volume, function, mapper, world_cameras, SIZE, sample_distance=step)
        for name, options in ANISOTROPIC_VARIANTS.items():
            run_ = _time_renderer(lambda options=options: ShearWarpRenderer(volume.array, volume.spacing, table,
                                                                            **options), cameras, SIZE)
            run_["rendered_spacing"] = run_.pop("spacing")
            run_["start"] = run_["start"].to_uint8()
            runs[name] = run_
        cpu_median = runs["vtk-cpu"]["times"].summary()["frame_seconds"]
        for name, run_ in runs.items():
            timing = run_["times"].summary()
            comparison = compare_images(run_["start"], runs["vtk-gpu"]["start"])
            rows.append({
                "projection": projection,
                "renderer": name,
                "rendered_spacing_mm": "x".join(f"{v:.4g}" for v in run_.get("rendered_spacing", volume.spacing)),
                "median_frame_seconds": timing["frame_seconds"],
                "p95_frame_seconds": timing["p95_frame_seconds"],
                "ratio_to_vtk_cpu": timing["frame_seconds"] / cpu_median,
                "setup_seconds": timing["setup_seconds"],
                "first_frame_seconds": run_.get("first_seconds", float("nan")),
                "psnr_foreground_db_vs_vtk_gpu": comparison.psnr_foreground,
                "ssim_vs_vtk_gpu": comparison.ssim,
                "frames": timing["frames"],
            })
        montage.append(np.concatenate([runs["vtk-gpu"]["start"], runs["shear-warp (default: resampled)"]["start"]],
                                      axis=1))
        report(progress, (index + 1) / len(projections))
    return rows, np.concatenate(montage, axis=0)


def _banding_rows(grids=BANDING_GRIDS) -> tuple[list[dict[str, Any]], dict[int, np.ndarray]]:
    """Banding metric of a shaded sphere (radius 18 mm in a 48^3 volume) for each normal grid."""
    field = sphere_field((48, 48, 48), 18.0)
    table = TransferTable.from_points([(-1, 1, 1, 1), (1, 1, 1, 1)], [(-1, 0), (0, 0), (1, 1)], (-25, 25))
    volume = Volume(field)
    camera = default_camera(volume, azimuth=20.0, elevation=15.0, parallel=True)
    images, rows = {}, []
    for grid in grids:
        renderer = ShearWarpRenderer(field, (1, 1, 1), table, shading=True, normal_grid=grid, specular=0.0)
        images[grid] = renderer.render(camera, 256, 256)
    interior = images[grids[-1]].rgba[..., 3] > 0.999
    for _ in range(3):
        interior[1:-1, 1:-1] &= interior[:-2, 1:-1] & interior[2:, 1:-1] & interior[1:-1, :-2] & interior[1:-1, 2:]
    for grid in grids:
        rows.append({"normal_grid": grid, "normals": len(NormalTable.build(grid).normals),
                     "banding": shading_banding(images[grid].over(), interior)})
    return rows, {grid: image.to_uint8() for grid, image in images.items()}


def _plot_random(path: Path, sizes: list[dict[str, Any]], transparency: list[dict[str, Any]]) -> Path:
    plt = pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    voxels = [row["voxels"] / 1e6 for row in sizes]
    left.plot(voxels, [row["median_frame_seconds"] for row in sizes], "o-", label="frame")
    left.plot(voxels, [row["composite_seconds"] for row in sizes], "s--", label="compositing")
    left.plot(voxels, [row["warp_seconds"] for row in sizes], "^--", label="warp")
    for row, x in zip(sizes, voxels):
        left.annotate(row["size"], (x, row["median_frame_seconds"]), fontsize=7, xytext=(3, 3),
                      textcoords="offset points")
    left.set_xlabel("volume size (million voxels), 100 % non-transparent")
    left.set_ylabel("seconds")
    left.set_title("Test 1: frame time against volume size")
    right.plot([row["transparent_percent"] for row in transparency],
               [row["median_frame_seconds"] for row in transparency], "o-", label="frame")
    right.plot([row["transparent_percent"] for row in transparency],
               [row["composite_seconds"] for row in transparency], "s--", label="compositing")
    right.set_xlabel("transparent voxels (%), 256^3")
    right.set_ylabel("seconds")
    right.set_title("Test 2: frame time against transparency")
    for axis in (left, right):
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
        axis.set_ylim(bottom=0)
    return save_figure(figure, path)


def _plot_ct(path: Path, summary: list[dict[str, Any]], runs: dict[str, dict[str, Any]]) -> Path:
    plt = pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [3, 2]})
    names = [row["renderer"] for row in summary]
    left.bar(names, [row["median_frame_seconds"] for row in summary],
             color=["0.55" if name.startswith("vtk") else "tab:blue" for name in names])
    left.set_yscale("log")
    left.set_ylabel("median frame time (s)")
    left.set_title("CT phantom, ct-bone, 512 x 512, parallel (grey: VTK)")
    left.tick_params(axis="x", labelrotation=35, labelsize=7)
    left.grid(True, axis="y", which="both", alpha=0.3)
    for name, run in runs.items():
        right.plot(run["times"].frames, "--" if name.startswith("vtk") else "-", label=name)
    right.set_yscale("log")
    right.set_xlabel(f"frame (camera turns {TURN_DEGREES:g} degrees per frame)")
    right.set_ylabel("frame time (s)")
    right.legend(fontsize=6)
    right.grid(True, which="both", alpha=0.3)
    return save_figure(figure, path)


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Run the shear-warp benchmark; write CSVs, plots, images and a JSON summary and return their paths.

    ``quick`` uses one random volume per configuration, fewer frames and skips the 512x512x128 volume: for
    checking that the benchmark runs, not for numbers.
    """
    configure_vtk()
    plt = pyplot()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    volumes, frames, ct_frames = (QUICK_VOLUMES, QUICK_FRAMES, QUICK_CT_FRAMES) if quick else (
        VOLUMES, FRAMES, CT_FRAMES)
    sizes = SIZES[:-1] if quick else SIZES
    steps = len(sizes) * volumes + len(TRANSPARENT_PERCENT) * volumes + 4 + len(CT_VARIANTS)
    done = 0

    def next_progress() -> ProgressCallback:
        nonlocal done
        done += 1
        return scaled(progress, (done - 1) / steps, done / steps)

    # Tests 1 and 2 of source 004.
    size_rows, transparency_rows = [], []
    for nx, ny, nz in sizes:
        for seed in range(volumes):
            volume = random_volume((nz, ny, nx), seed=seed)
            size_rows.append(_random_row({"size": f"{nx}x{ny}x{nz}", "seed": seed}, volume, frames, next_progress()))
    for percent in TRANSPARENT_PERCENT:
        for seed in range(volumes):
            volume = random_volume((256, 256, 256), transparent_fraction=percent / 100.0, seed=100 + seed)
            transparency_rows.append(
                _random_row({"transparent_percent": percent, "seed": seed}, volume, frames, next_progress()))

    # CT phantom against VTK.
    phantom = ct_volume(quick)
    function = transfer_function_for(phantom, PRESET, shading=False)
    preset_shading = transfer_function_for(phantom, PRESET, shading=True).shading
    table = function.to_table(phantom.value_range)
    step = default_sample_distance(phantom)
    world_cameras = _turning_cameras(phantom, ct_frames)
    cameras = [camera_in_frame(camera, phantom.local_to_world) for camera in world_cameras]
    runs: dict[str, dict[str, Any]] = {}
    for name, mapper in (("vtk-cpu", "cpu"), ("vtk-gpu", "gpu")):
        runs[name] = time_vtk_mapper(phantom, function, mapper, world_cameras, SIZE, sample_distance=step)
        report(next_progress(), 1.0)
    material = {"ambient": preset_shading.ambient, "diffuse": preset_shading.diffuse,
                "specular": preset_shading.specular, "specular_power": preset_shading.specular_power}
    for name, options in CT_VARIANTS.items():
        options = {**options, **(material if options.get("shading") else {})}
        runs[name] = _time_renderer(
            lambda options=options: ShearWarpRenderer(phantom.array, phantom.spacing, table, **options), cameras, SIZE)
        runs[name]["start"] = runs[name]["start"].to_uint8()
        report(next_progress(), 1.0)

    reference = runs["vtk-gpu"]["start"]
    cpu_median = runs["vtk-cpu"]["times"].summary()["frame_seconds"]
    full_median = runs["shear-warp"]["times"].summary()["frame_seconds"]
    ct_rows = []
    for name, run_ in runs.items():
        timing = run_["times"].summary()
        shaded = CT_VARIANTS.get(name, {}).get("shading", False)
        comparison = None if shaded else compare_images(run_["start"], reference)
        setup = run_.get("setup_stats", {})
        ct_rows.append({
            "renderer": name,
            "median_frame_seconds": timing["frame_seconds"],
            "mean_frame_seconds": timing["mean_frame_seconds"],
            "weighted_mean_frame_seconds": timing["weighted_mean_frame_seconds"],
            "p95_frame_seconds": timing["p95_frame_seconds"],
            "ratio_to_vtk_cpu": timing["frame_seconds"] / cpu_median,
            "slowdown_against_shear_warp": timing["frame_seconds"] / full_median,
            "setup_seconds": timing["setup_seconds"],
            "first_frame_seconds": run_.get("first_seconds", float("nan")),
            "encoding_seconds": setup.get("encoding_seconds", float("nan")),
            "encoded_bytes_per_copy": float(np.mean([setup[f"encoded_bytes_{a}"] for a in "xyz"])) if setup else
            float("nan"),
            "raw_bytes": setup.get("raw_bytes", float("nan")),
            **run_.get("stats", {}),
            "psnr_foreground_db_vs_vtk_gpu": comparison.psnr_foreground if comparison else float("nan"),
            "ssim_vs_vtk_gpu": comparison.ssim if comparison else float("nan"),
            "frames": timing["frames"],
        })

    # The anisotropic CT, parallel and perspective.
    anisotropic_rows, anisotropic_montage = _anisotropic_rows(ct_frames, next_progress())

    # Banding: coarse and fine normal tables on the CT and on a sphere.
    banding, sphere_images = _banding_rows()
    coarse = ShearWarpRenderer(phantom.array, phantom.spacing, table, shading=True, normal_grid=8, **material)
    coarse_start = coarse.render(cameras[0], SIZE, SIZE).to_uint8()
    report(next_progress(), 1.0)

    sizes_mean = _averaged(size_rows, "size")
    transparency_mean = _averaged(transparency_rows, "transparent_percent")
    written = [
        write_csv(out_dir / "shear_warp_sizes.csv", size_rows),
        write_csv(out_dir / "shear_warp_transparency.csv", transparency_rows),
        write_csv(out_dir / "shear_warp_ct.csv", ct_rows),
        write_csv(out_dir / "shear_warp_banding.csv", banding),
        write_csv(out_dir / "shear_warp_anisotropic.csv", anisotropic_rows),
        _plot_random(out_dir / "shear_warp_tests_1_2.png", sizes_mean, transparency_mean),
        _plot_ct(out_dir / "shear_warp_ct.png", ct_rows, runs),
    ]
    images = {
        "shear_warp_ct_start.png": runs["shear-warp"]["start"],
        "shear_warp_ct_vtk_gpu.png": reference,
        "shear_warp_ct_vtk_cpu.png": runs["vtk-cpu"]["start"],
        "shear_warp_ct_difference_vs_vtk_gpu.png": difference_heatmap(runs["shear-warp"]["start"], reference),
        "shear_warp_ct_banding_grid8_vs_grid128.png": np.concatenate(
            [coarse_start, runs["shear-warp shaded"]["start"]], axis=1),
        "shear_warp_sphere_banding.png": np.concatenate([sphere_images[grid] for grid in BANDING_GRIDS], axis=1),
        "shear_warp_anisotropic_frames.png": anisotropic_montage,
    }
    for name, image in images.items():
        plt.imsave(out_dir / name, image)
        written.append(out_dir / name)

    def median(name: str) -> float:
        return runs[name]["times"].summary()["frame_seconds"]

    written.append(write_json(out_dir / "shear_warp.json", {
        "benchmark": "shear-warp",
        "machine": machine_info(),
        "quick": quick,
        "image_size": [SIZE, SIZE],
        "random_volumes": {
            "transfer_function": "grey ramp; opacity 0 at value 0, linear to 0.3 per mm at 255; shading on",
            "volumes_per_configuration": volumes,
            "frames_per_volume": frames,
            "test_1_sizes": sizes_mean,
            "test_2_transparency": transparency_mean,
        },
        "ct_phantom": {
            "shape": list(phantom.array.shape),
            "spacing_mm": list(phantom.spacing),
            "preset": PRESET,
            "frames": ct_frames,
            "vtk_sample_distance_mm": step,
            "summary": ct_rows,
            "shear_warp_over_vtk_cpu": median("shear-warp") / cpu_median,
            "speed_up_from_rle": median("shear-warp (no RLE)") / median("shear-warp"),
            "speed_up_from_early_termination": median("shear-warp (no early termination)") / median("shear-warp"),
            "speed_up_from_both": median("shear-warp (no RLE + no early termination)") / median("shear-warp"),
        },
        "anisotropic_ct": {
            "shape": list(ANISOTROPIC_SHAPE),
            "spacing_mm": list(ANISOTROPIC_SPACING),
            "preset": PRESET,
            "frames": ct_frames,
            "summary": anisotropic_rows,
            "montage": "rows: parallel, perspective; columns: vtk-gpu, shear-warp (default: resampled)",
        },
        "banding": banding,
        "notes": [
            "Frame times are wall-clock medians; set-up (classification, encoding, normals) and the first frame "
            "are reported apart.",
            "VTK's volume mappers do not use vtkSMPTools; the fixed-point mapper threads on its own.",
            "vtk-gpu runs on Mesa's llvmpipe software rasteriser without a GPU.",
            "PSNR is over the foreground of the start frame against vtk-gpu; shear-warp's remaining difference is "
            "its two bilinear resamplings and pre-classification (see algorithms.rendering.shear_warp).",
        ],
    }))
    report(progress, 1.0)
    return written


__all__ = ["CT_VARIANTS", "RANDOM_TABLE", "SIZES", "TRANSPARENT_PERCENT", "run"]
