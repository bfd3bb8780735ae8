"""The benchmarks run for real on tiny workloads: every file is written, the tables have their columns and rows,
and the numbers obey what they measure (same surfaces as VTK, positive times, ratios that match their times).

Only the size of each workload is reduced here (sizes, frames, image sizes, slice counts, a cropped Colin 27);
every extraction, render and timing is the benchmark's own. Speed itself is not asserted.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from app.bench import marching_cubes, render, shear_warp, slicing, voxel_surfaces

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MACHINE_KEYS = {"python", "platform", "cpus", "numpy", "vtk", "vtk_smp_backend"}
#: Relative tolerance of a ratio recomputed from the CSV: every number there is rounded to 6 significant digits.
ROUNDING = 3e-5


# --------------------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------------------
def check_written(paths, out_dir: Path, expected_names) -> dict[str, Path]:
    """Every returned file exists inside ``out_dir``, is non-empty and is what its suffix says; returns them by
    path relative to ``out_dir``, which must be exactly ``expected_names``."""
    by_name = {}
    for path in map(Path, paths):
        assert path.is_file() and path.stat().st_size > 0, path
        name = path.relative_to(out_dir).as_posix()
        assert name not in by_name, f"{name} returned twice"
        by_name[name] = path
        if path.suffix == ".png":
            assert path.read_bytes()[:8] == PNG_SIGNATURE, path
        elif path.suffix == ".json":
            json.loads(path.read_text())
        else:
            assert path.suffix == ".csv", path
    assert set(by_name) == set(expected_names)
    return by_name


def png_size(path: Path) -> tuple[int, int]:
    """Width and height from a PNG's IHDR chunk."""
    return struct.unpack(">II", path.read_bytes()[16:24])


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
        return list(reader.fieldnames), rows


def number(row: dict[str, str], key: str) -> float:
    return float(row[key])


def check_run_json(path: Path, *, nested: str | None = None) -> dict:
    """A quick run's JSON: ``"quick": true`` (at the top or in ``nested``) and a description of the machine."""
    data = json.loads(path.read_text())
    assert (data[nested] if nested else data)["quick"] is True
    assert MACHINE_KEYS <= set(data["machine"]) and data["machine"]["cpus"] >= 1
    return data


class Progress:
    """Records a benchmark's progress calls."""

    def __init__(self) -> None:
        self.values: list[float] = []

    def __call__(self, fraction: float) -> None:
        self.values.append(fraction)

    def check(self) -> None:
        """Reported at least once, never backwards, within [0, 1], and finished."""
        assert self.values and self.values == sorted(self.values)
        assert 0.0 <= self.values[0] and self.values[-1] == pytest.approx(1.0)


@pytest.fixture(scope="module")
def colin_crop(tmp_path_factory):
    """A 40^3 voxel block from the middle of the real Colin 27 MRI (geometry kept), written as NIfTI: the
    benchmarks' real brain volume at 1 % of its size."""
    from app.io import load_volume, save_volume
    from app.samples import sample_path

    crop = load_volume(sample_path("mri")).crop((70, 110), (80, 120), (70, 110))
    return save_volume(crop, tmp_path_factory.mktemp("colin") / "colin_crop.nii.gz")


# --------------------------------------------------------------------------------------------------------------
# Marching cubes
# --------------------------------------------------------------------------------------------------------------
def test_marching_cubes_bench_extracts_vtks_surface_and_times_every_method(tmp_path, monkeypatch, colin_crop):
    tori = (16, 24)
    monkeypatch.setattr(marching_cubes, "QUICK_SYNTHETIC_SIZES", tori)
    monkeypatch.setattr(marching_cubes, "COLIN27", colin_crop)
    progress = Progress()
    files = check_written(marching_cubes.run(tmp_path, quick=True, progress=progress), tmp_path,
                          ["marching_cubes.csv", "marching_cubes.png", "marching_cubes.json"])
    progress.check()

    columns, rows = read_csv(files["marching_cubes.csv"])
    assert columns == list(marching_cubes.COLUMNS)
    methods = [("ours", "numba threads"), ("vtkMarchingCubes", "Sequential"), ("vtkFlyingEdges3D", "Sequential"),
               ("vtkFlyingEdges3D", "STDThread")]
    # CT phantom: two isovalues, each without and with normals; Colin 27 and each torus: one isovalue, no normals.
    cases = {("CT phantom", "300", "False"), ("CT phantom", "300", "True"), ("CT phantom", "-300", "False"),
             ("CT phantom", "-300", "True"), ("Colin 27 T1", None, "False")}
    cases |= {(f"noisy torus {n}^3", "0", "False") for n in tori}
    assert len(rows) == len(cases) * len(methods)
    groups: dict[tuple[str, str, str], dict[tuple[str, str], dict[str, str]]] = {}
    for row in rows:
        groups.setdefault((row["dataset"], row["iso"], row["normals"]), {})[(row["method"], row["backend"])] = row
    assert {(d, None if d.startswith("Colin") else iso, n) for d, iso, n in groups} == cases
    assert all(list(group) == methods for group in groups.values())

    for (dataset, iso, normals), group in groups.items():
        ours, vtk_mc = group[methods[0]], group[methods[1]]
        # One vertex per cut edge on both sides; triangles differ only on ambiguous cells, where Bourke's tables and
        # VTK's split a cell differently (in the CT phantom about 0.1 % of the triangles: thin bone, air cells).
        assert ours["points"] == vtk_mc["points"], (dataset, iso, normals)
        if dataset == "CT phantom":
            assert int(ours["triangles"]) == pytest.approx(int(vtk_mc["triangles"]), rel=0.005), (iso, normals)
        assert int(ours["triangles"]) > 0
        assert int(ours["voxels"]) == math.prod(map(int, ours["shape"].split("x")))
        assert number(ours, "ratio_to_ours") == 1.0 and number(ours, "peak_mb") > 0
        for row in group.values():
            assert 0 < number(row, "min_s") <= number(row, "median_s") and number(row, "first_call_s") > 0
            assert row["repeats"] == "3" and number(row, "output_mb") > 0
            assert number(row, "ratio_to_ours") == pytest.approx(
                number(row, "median_s") / number(ours, "median_s"), rel=ROUNDING)
            assert number(row, "triangles_per_s") == pytest.approx(
                int(row["triangles"]) / number(row, "median_s"), rel=ROUNDING)
            if row is not ours:
                assert row["peak_mb"] == ""  # tracemalloc cannot see VTK's C++ allocations
        # Ours and flying edges with threads are timed in turns; the others alone.
        assert number(ours, "paired_ratio_to_ours") == 1.0 and number(group[methods[3]], "paired_ratio_to_ours") > 0
        assert group[methods[1]]["paired_ratio_to_ours"] == group[methods[2]]["paired_ratio_to_ours"] == ""
    assert int(groups[("CT phantom", "300", "True")][methods[0]]["voxels"]) == 256 * 256 * 88  # the quick grid

    data = check_run_json(files["marching_cubes.json"])
    assert data["benchmark"] == "marching-cubes" and len(data["rows"]) == len(rows)
    assert list(data["numba_compile_s"]) == ["int16"] and data["numba_compile_s"]["int16"] > 0
    assert set(data["numba_cache"]) == {"count_layers", "fill_layers", "merge_on_samples"}
    summary = data["ours_over_flying_edges_stdthread"]
    assert len(summary) == len(cases)
    for entry in summary:
        group = groups[(entry["dataset"], f"{entry['iso']:.6g}", str(entry["normals"]))]
        assert entry["ratio"] == pytest.approx(number(group[methods[0]], "median_s")
                                               / number(group[methods[3]], "median_s"), rel=ROUNDING)
        assert entry["paired_ratio"] == pytest.approx(1.0 / number(group[methods[3]], "paired_ratio_to_ours"),
                                                      rel=ROUNDING)


def test_interleaved_timing_rotates_the_order_and_pairs_the_repeats():
    from app.pipeline.timing import Timing, paired_ratio, time_interleaved

    calls = []
    timings, results = time_interleaved([lambda: calls.append("a") or "A", lambda: calls.append("b") or "B"],
                                        repeats=4, warmup=1)
    assert calls == ["a", "b"] + ["a", "b", "b", "a", "a", "b", "b", "a"]  # warm-up, then the order alternates
    assert results == ["A", "B"] and [len(t.samples) for t in timings] == [4, 4]
    assert paired_ratio(Timing([2.0, 3.0, 10.0]), Timing([1.0, 1.0, 1.0])) == 3.0
    assert paired_ratio(Timing([2.0, 6.0, 4.0]), Timing([1.0, 4.0, 1.0])) == 2.0  # not 4 / 1 of the medians


# --------------------------------------------------------------------------------------------------------------
# Voxel surfaces
# --------------------------------------------------------------------------------------------------------------
def test_voxel_surfaces_bench_tower_strips_save_memory_on_the_same_triangles(tmp_path, monkeypatch, colin_crop):
    from app.datasets import FAMILIES

    settings = dataclasses.replace(voxel_surfaces.QUICK, sizes=(8, 12), memory_models=2, stripper_models=1,
                                   render_models=1, frames=2, timing_repeats=1, vtk_timing_repeats=1,
                                   colin_thresholds=(70,), real_frames=3)
    monkeypatch.setattr(voxel_surfaces, "QUICK", settings)
    monkeypatch.setattr(voxel_surfaces, "WINDOW_SIZE", (128, 128))
    monkeypatch.setattr(voxel_surfaces, "COLIN_PATHS", (colin_crop,))
    progress = Progress()
    tables = ["voxel_surfaces_memory.csv", "voxel_surfaces_render.csv", "voxel_surfaces_extraction.csv"]
    files = check_written(voxel_surfaces.run(tmp_path, quick=True, progress=progress), tmp_path,
                          tables + [f"voxel_surfaces_{family}.png" for family in FAMILIES]
                          + ["voxel_surfaces_real.png", "voxel_surfaces.json"])
    progress.check()
    memory, rendered, extraction = (read_csv(files[name]) for name in tables)

    # Expected rows: per model baseline, tower, hybrid (+ vtkStripper and its de-indexed count on the first
    # stripper_models models); one worst-case model per size; the two real volumes (threshold 70 and labels).
    real = ["colin27 T>=70", "colin27 labels>0"]
    models = {family: 1 if family == "worst-case" else settings.memory_models for family in FAMILIES}
    memory_rows = sum(3 * m + 2 * min(m, settings.stripper_models) for m in models.values()) * len(settings.sizes)
    assert len(memory[1]) == memory_rows + 5 * len(real)
    assert len(rendered[1]) == 3 * (len(FAMILIES) * len(settings.sizes) + len(real))
    assert len(extraction[1]) == 7 * (len(FAMILIES) * len(settings.sizes) + len(real))
    assert memory[0][:5] == rendered[0][:5] == extraction[0][:5] == ["dataset", "n", "shape", "model", "faces"]

    by_model: dict[tuple[str, str, str], dict[str, dict[str, str]]] = {}
    for row in memory[1]:
        by_model.setdefault((row["dataset"], row["n"], row["model"]), {})[row["representation"]] = row
    assert {dataset for dataset, _, _ in by_model} == set(FAMILIES) | set(real)
    for key, rows in by_model.items():
        baseline, tower, hybrid = rows["baseline"], rows["tower"], rows["hybrid"]
        faces = int(baseline["faces"])
        assert faces > 0, key
        # The same surface three ways: two triangles per voxel face.
        assert baseline["triangles"] == tower["triangles"] == hybrid["triangles"] == str(2 * faces), key
        assert (int(baseline["vertices"]), int(baseline["indices"])) == (4 * faces, 6 * faces), key
        # Strips need no indices, so they take fewer bytes than the indexed baseline.
        assert tower["indices"] == "0" and int(tower["bytes_32"]) < int(baseline["bytes_32"]), key
        assert int(hybrid["bytes_32"]) <= int(baseline["bytes_32"]), key
        if "vtkStripper" in rows:
            assert rows["vtkStripper"]["triangles"] == str(2 * faces), key

    frames = {row["dataset"]: row["frames"] for row in rendered[1]}
    assert frames == {**{family: str(settings.frames) for family in FAMILIES},
                      **{name: str(settings.real_frames) for name in real}}
    for row in rendered[1]:
        assert row["triangles"] == str(2 * int(row["faces"]))
        assert 0 < number(row, "mean_ms") and 0 < number(row, "median_ms")

    baseline_seconds = {}
    for row in extraction[1]:
        assert number(row, "median_s") > 0
        key = (row["dataset"], row["n"], row["model"])
        if row["method"] == "baseline":
            baseline_seconds[key] = number(row, "median_s")
            assert number(row, "ratio_to_baseline") == 1.0
        assert number(row, "ratio_to_baseline") == pytest.approx(
            number(row, "median_s") / baseline_seconds[key], rel=ROUNDING)
        assert row["smp_backend"] in (("",) if row["method"] in ("baseline", "tower", "hybrid")
                                      else voxel_surfaces.VTK_BACKENDS)

    data = check_run_json(files["voxel_surfaces.json"])
    assert data["benchmark"] == "voxel-surfaces" and data["skipped"] == []
    assert data["settings"] == json.loads(json.dumps(dataclasses.asdict(settings)))
    assert data["real_data"]["colin27"] == str(colin_crop)


# --------------------------------------------------------------------------------------------------------------
# Direct volume rendering (render, then texture slicing)
# --------------------------------------------------------------------------------------------------------------
def test_render_bench_images_agree_with_vtk_and_accelerations_keep_the_image(tmp_path, monkeypatch):
    from algorithms.rendering.raymarch import LIGHTING_MODELS

    size, frames = 128, 3  # three frames: a median that differs from the mean
    monkeypatch.setattr(render, "QUICK_SIZE", size)
    monkeypatch.setattr(render, "QUICK_FRAMES", frames)
    monkeypatch.setattr(slicing, "QUICK_SLICE_COUNTS", (32,))
    renderers = ["vtk-gpu", "vtk-cpu", "vtk-gpu-shaded", "vtk-cpu-shaded"]
    renderers += list(render.SOFTWARE_RENDERERS)
    renderers += [name for name, _ in render.EXTRA_RENDERERS]
    assert {f"raymarch-{lighting}" for lighting in LIGHTING_MODELS} <= set(renderers)
    assert {"slicing-shaded", "raymarch-emission-jittered", "slicing-jittered"} <= set(renderers)
    expected = ["render_summary.csv", "render_ablation.csv", "render_frames.csv", "render_frame_times.png",
                "render_medians.png", "render_difference_raymarch-emission_vs_vtk-gpu.png", "render.json"]
    expected += [f"render_start_{name}.png" for name in renderers]
    expected += [f"slicing/{name}" for name in (
        "slicing_frame_times.csv", "slicing_quality.csv", "slicing_axis_switch.csv", "slicing_frame_times.png",
        "slicing_quality.png", "slicing_axis_switch.png", "slicing_frames.png", "slicing_axis_switch_frames.png",
        "slicing.json")]
    progress = Progress()
    files = check_written(render.run(tmp_path, quick=True, progress=progress), tmp_path, expected)
    progress.check()
    assert {png_size(files[f"render_start_{name}.png"]) for name in renderers} == {(size, size)}

    _, summary = read_csv(files["render_summary.csv"])
    assert [row["renderer"] for row in summary] == renderers
    cpu_median = next(number(row, "median_frame_seconds") for row in summary if row["renderer"] == "vtk-cpu")
    for row in summary:
        assert row["frames"] == str(frames)
        assert 0 < number(row, "median_frame_seconds") <= number(row, "p95_frame_seconds")
        assert number(row, "setup_seconds") > 0
        assert number(row, "ratio_to_vtk_cpu") == pytest.approx(
            number(row, "median_frame_seconds") / cpu_median, rel=ROUNDING)
        psnr = number(row, "psnr_foreground_db")
        if row["renderer"] == row["reference"]:
            assert psnr == math.inf and number(row, "ssim") == pytest.approx(1.0)
        elif row["reference"] == "none":  # scatter: VTK has no such light model to compare with
            assert row["renderer"] == "raymarch-scatter" and math.isnan(psnr)
        else:
            assert math.isfinite(psnr) and psnr > 15.0, row
        assert math.isnan(number(row, "compile_seconds")) != row["renderer"].startswith("raymarch")
        shaded = row["renderer"].startswith("raymarch-phong") or "shaded" in row["renderer"]
        assert row["reference"] in (("vtk-gpu-shaded",) if shaded else ("vtk-gpu", "none"))
        # Against the CPU ray caster of the same shading: every one of ours but scatter.
        against_cpu = number(row, "psnr_foreground_db_vs_vtk_cpu")
        if row["reference"] == "none":
            assert row["reference_cpu"] == "none" and math.isnan(against_cpu)
        elif row["renderer"] != row["reference_cpu"]:
            assert row["reference_cpu"] == row["reference"].replace("gpu", "cpu")
            assert math.isfinite(against_cpu) and against_cpu > 15.0, row
        # Jittered renderers (and only they) also report the mean of the jitter passes of their start frame.
        jittered = "jittered" in row["renderer"] or row["renderer"] == "raymarch-scatter"
        assert row["jitter"] == str(jittered)
        passes = number(row, "psnr_foreground_db_passes")
        if jittered and row["reference"] != "none":
            assert math.isfinite(passes) and passes > 15.0, row
        else:
            assert math.isnan(passes)

    _, ablation = read_csv(files["render_ablation.csv"])
    by_setting = {row["setting"]: row for row in ablation}
    assert list(by_setting) == list(render.ABLATIONS)
    both_off = by_setting["both off"]
    for setting, row in by_setting.items():
        termination, skipping = render.ABLATIONS[setting]
        assert row["early_termination"] == str(termination is not None)
        assert row["empty_space_skipping"] == str(skipping)
        assert number(row, "speed_up_over_both_off") == pytest.approx(
            number(both_off, "median_frame_seconds") / number(row, "median_frame_seconds"), rel=ROUNDING)
        assert number(row, "samples_per_ray") <= number(both_off, "samples_per_ray")
        if termination is None:
            assert number(row, "early_terminated") == 0.0
        if not skipping:
            assert number(row, "skipped_fraction") == 0.0
        # Stopping at 99 % opacity changes a pixel by at most 1 % (plus 8-bit rounding).
        assert number(row, "max_start_frame_difference") <= 0.01 + 1 / 255
    # Empty-space skipping leaves the image bit-identical.
    assert number(by_setting["early termination off"], "max_start_frame_difference") == 0.0
    assert (by_setting["both on"]["max_start_frame_difference"]
            == by_setting["empty-space skipping off"]["max_start_frame_difference"])

    _, frame_rows = read_csv(files["render_frames.csv"])
    assert len(frame_rows) == (len(renderers) + len(render.ABLATIONS)) * frames
    assert all(number(row, "seconds") > 0 for row in frame_rows)

    data = check_run_json(files["render.json"])
    assert data["image_size"] == [size, size] and data["frames"] == frames
    assert data["jitter_passes_accumulated"] == render.PASSES
    assert data["volume"]["shape"] == [88, 256, 256]  # the CT phantom on the quick grid
    check_slicing(files, slicing.QUICK_SLICE_COUNTS, slicing.QUICK_SWITCH_AZIMUTHS)


def check_slicing(files: dict[str, Path], counts, azimuths) -> None:
    """The texture-slicing part of the render benchmark (``slicing/`` files)."""
    columns, times = read_csv(files["slicing/slicing_frame_times.csv"])
    assert columns == ["path", "slices", "label", "frame_seconds", "cpu_seconds", "draw_seconds", "ratio_to_vtk_gpu",
                       "ratio_to_vtk_cpu", "texels", "texel_size_mm", "slice_distance_mm", "path_step_mm"]
    labels = [str(count) for count in counts] + ["default"]
    assert [(row["path"], row["label"]) for row in times] == [
        (path, label) for label in labels for path in ("float", "uint8", "gl")] + [("vtk-gpu", ""), ("vtk-cpu", "")]
    vtk = {row["path"]: number(row, "frame_seconds") for row in times if row["path"].startswith("vtk")}
    for row in times:
        assert number(row, "frame_seconds") > 0
        assert number(row, "ratio_to_vtk_gpu") == pytest.approx(number(row, "frame_seconds") / vtk["vtk-gpu"],
                                                                rel=ROUNDING)
        assert number(row, "ratio_to_vtk_cpu") == pytest.approx(number(row, "frame_seconds") / vtk["vtk-cpu"],
                                                                rel=ROUNDING)
        if row["path"] == "gl":
            assert number(row, "cpu_seconds") > 0 and number(row, "draw_seconds") > 0

    _, quality = read_csv(files["slicing/slicing_quality.csv"])
    assert len(quality) == 2 * len(labels) * 3  # two presets, every slice count, three paths
    assert {row["preset"] for row in quality} == {slicing.PRESET, slicing.FAINT_PRESET}
    for row in quality:
        assert math.isfinite(number(row, "psnr_foreground")) and number(row, "psnr_foreground") > 15.0, row

    _, switch = read_csv(files["slicing/slicing_axis_switch.csv"])
    assert [number(row, "azimuth_degrees") for row in switch] == pytest.approx(list(azimuths))
    # The turn passes 45 degrees, where the axis-aligned stack along y gives way to the one along x.
    axes = [row["stack_axis"] for row in switch]
    assert axes[0] == "y" and axes[-1] == "x" and axes == sorted(axes, key="yx".index)
    assert math.isnan(number(switch[0], "axis_step_rmse"))
    assert all(number(row, "axis_step_rmse") >= 0 for row in switch[1:])

    data = check_run_json(files["slicing/slicing.json"], nested="configuration")
    first_x = next(row for row in switch if row["stack_axis"] == "x")
    assert data["axis_switch"]["switch_azimuth_degrees"] == pytest.approx(number(first_x, "azimuth_degrees"))
    assert data["configuration"]["default_slices"] == int(next(row["slices"] for row in times
                                                               if row["label"] == "default"))


# --------------------------------------------------------------------------------------------------------------
# Shear-warp
# --------------------------------------------------------------------------------------------------------------
def test_shear_warp_bench_ratios_match_times_and_ablations_turn_accelerations_off(tmp_path, monkeypatch):
    sizes = ((32, 32, 16), (48, 32, 24), (64, 64, 64))  # the quick run leaves out the last, as it does 512x512x128
    percents = (0, 50)
    frames, ct_frames, size = 2, 3, 128  # three CT frames: a median that differs from the mean
    monkeypatch.setattr(shear_warp, "SIZE", size)
    monkeypatch.setattr(shear_warp, "SIZES", sizes)
    monkeypatch.setattr(shear_warp, "TRANSPARENT_PERCENT", percents)
    monkeypatch.setattr(shear_warp, "QUICK_FRAMES", frames)
    monkeypatch.setattr(shear_warp, "QUICK_CT_FRAMES", ct_frames)
    monkeypatch.setattr(shear_warp, "ANISOTROPIC_SHAPE", (48, 96, 96))  # the real CT's voxel size, a smaller grid
    tables = ["shear_warp_sizes.csv", "shear_warp_transparency.csv", "shear_warp_ct.csv", "shear_warp_banding.csv",
              "shear_warp_anisotropic.csv"]
    images = ["shear_warp_ct_start.png", "shear_warp_ct_vtk_gpu.png", "shear_warp_ct_vtk_cpu.png",
              "shear_warp_ct_difference_vs_vtk_gpu.png", "shear_warp_ct_banding_grid8_vs_grid128.png",
              "shear_warp_sphere_banding.png", "shear_warp_anisotropic_frames.png"]
    progress = Progress()
    files = check_written(shear_warp.run(tmp_path, quick=True, progress=progress), tmp_path,
                          tables + images + ["shear_warp_tests_1_2.png", "shear_warp_ct.png", "shear_warp.json"])
    progress.check()
    assert png_size(files["shear_warp_ct_start.png"]) == (size, size)
    assert png_size(files["shear_warp_ct_banding_grid8_vs_grid128.png"]) == (2 * size, size)

    _, ct = read_csv(files["shear_warp_ct.csv"])
    by_name = {row["renderer"]: row for row in ct}
    assert list(by_name) == ["vtk-cpu", "vtk-gpu", *shear_warp.CT_VARIANTS]
    cpu, full = number(by_name["vtk-cpu"], "median_frame_seconds"), number(by_name["shear-warp"],
                                                                           "median_frame_seconds")
    for name, row in by_name.items():
        median = number(row, "median_frame_seconds")
        assert row["frames"] == str(ct_frames) and median > 0 and number(row, "setup_seconds") > 0
        assert number(row, "ratio_to_vtk_cpu") == pytest.approx(median / cpu, rel=ROUNDING), name
        assert number(row, "slowdown_against_shear_warp") == pytest.approx(median / full, rel=ROUNDING), name
        psnr = number(row, "psnr_foreground_db_vs_vtk_gpu")
        if name == "vtk-gpu":
            assert psnr == math.inf
        elif shear_warp.CT_VARIANTS.get(name, {}).get("shading"):
            assert math.isnan(psnr)  # shaded: not compared with the unshaded reference
        else:
            assert math.isfinite(psnr) and psnr > 15.0, name
        if not name.startswith("vtk"):
            assert number(row, "first_frame_seconds") > 0 and number(row, "voxels_composited") > 0
    # The ablations really turn the accelerations off: no encoding (every voxel visited) and no opaque skipping.
    rle = by_name["shear-warp"]
    assert number(rle, "encoded_bytes_per_copy") < number(rle, "raw_bytes")
    assert number(rle, "voxels_skipped_transparent") > 0 and number(rle, "pixels_skipped_opaque") > 0
    for name in ("shear-warp (no RLE)", "shear-warp (no RLE + no early termination)"):
        row = by_name[name]
        assert number(row, "encoded_bytes_per_copy") == number(row, "raw_bytes")
        assert number(row, "voxels_skipped_transparent") == 0
    for name in ("shear-warp (no early termination)", "shear-warp (no RLE + no early termination)"):
        assert number(by_name[name], "pixels_skipped_opaque") == 0
    # Run-length encoding only skips transparent voxels: the image is the same.
    assert number(by_name["shear-warp (no RLE)"], "psnr_foreground_db_vs_vtk_gpu") == pytest.approx(
        number(rle, "psnr_foreground_db_vs_vtk_gpu"))

    _, size_rows = read_csv(files["shear_warp_sizes.csv"])
    assert [row["size"] for row in size_rows] == [f"{x}x{y}x{z}" for x, y, z in sizes[:-1]]
    _, transparency = read_csv(files["shear_warp_transparency.csv"])
    assert [int(row["transparent_percent"]) for row in transparency] == list(percents)
    for row in size_rows + transparency:
        assert number(row, "raw_bytes") == pytest.approx(int(row["voxels"]), rel=ROUNDING)  # uint8: a byte a voxel
        assert 0 < number(row, "median_frame_seconds") and number(row, "setup_seconds") > 0
    assert [int(row["voxels"]) for row in size_rows] == [x * y * z for x, y, z in sizes[:-1]]
    # 100 % non-transparent volumes have nothing to skip; half transparent ones do.
    skipped = [number(row, "voxels_skipped_transparent") for row in size_rows + transparency]
    assert skipped[:-1] == [0.0] * (len(skipped) - 1) and skipped[-1] > 0

    # The anisotropic CT: each projection against VTK's ray casters with the same projection.
    assert png_size(files["shear_warp_anisotropic_frames.png"]) == (2 * size, 2 * size)
    _, anisotropic = read_csv(files["shear_warp_anisotropic.csv"])
    names = ["vtk-cpu", "vtk-gpu", *shear_warp.ANISOTROPIC_VARIANTS]
    assert [(row["projection"], row["renderer"]) for row in anisotropic] == [
        (projection, name) for projection in ("parallel", "perspective") for name in names]
    for projection in ("parallel", "perspective"):
        group = {row["renderer"]: row for row in anisotropic if row["projection"] == projection}
        cpu = number(group["vtk-cpu"], "median_frame_seconds")
        for name, row in group.items():
            assert row["frames"] == str(ct_frames) and number(row, "median_frame_seconds") > 0
            assert number(row, "ratio_to_vtk_cpu") == pytest.approx(number(row, "median_frame_seconds") / cpu,
                                                                    rel=ROUNDING)
            psnr = number(row, "psnr_foreground_db_vs_vtk_gpu")
            assert psnr == math.inf if name == "vtk-gpu" else (math.isfinite(psnr) and psnr > 15.0), (projection, row)
        # By default the 1.5 mm slices are resampled to the 0.96 mm in-plane spacing; the own grid is kept as is.
        resampled = [float(v) for v in group["shear-warp (default: resampled)"]["rendered_spacing_mm"].split("x")]
        assert resampled == pytest.approx([0.96, 0.96, 0.96], rel=0.03)
        assert group["shear-warp (own grid)"]["rendered_spacing_mm"] == "0.96x0.96x1.5"
    assert json.loads(files["shear_warp.json"].read_text())["anisotropic_ct"]["spacing_mm"] == [0.96, 0.96, 1.5]

    _, banding = read_csv(files["shear_warp_banding.csv"])
    assert [int(row["normal_grid"]) for row in banding] == list(shear_warp.BANDING_GRIDS)
    normals = [int(row["normals"]) for row in banding]
    assert normals == sorted(normals) and len(set(normals)) == len(normals)
    assert number(banding[-1], "banding") < number(banding[0], "banding")  # finer normal grid, less banding

    data = check_run_json(files["shear_warp.json"])
    summary = data["ct_phantom"]
    assert summary["frames"] == ct_frames and summary["shape"] == [88, 256, 256]
    assert data["random_volumes"]["volumes_per_configuration"] == shear_warp.QUICK_VOLUMES
    assert summary["shear_warp_over_vtk_cpu"] == pytest.approx(number(rle, "ratio_to_vtk_cpu"), rel=ROUNDING)
    for key, name in (("speed_up_from_rle", "shear-warp (no RLE)"),
                      ("speed_up_from_early_termination", "shear-warp (no early termination)"),
                      ("speed_up_from_both", "shear-warp (no RLE + no early termination)")):
        assert summary[key] == pytest.approx(number(by_name[name], "slowdown_against_shear_warp"), rel=ROUNDING)
    assert np.isfinite([row["banding"] for row in data["banding"]]).all()


# --------------------------------------------------------------------------------------------------------------
# Cut-aways
# --------------------------------------------------------------------------------------------------------------
def test_cutaway_bench_times_cut_uncut_and_premasked_frames_in_turns(tmp_path, monkeypatch):
    from app.bench import cutaway

    monkeypatch.setattr(cutaway, "VOLUME_MODES", ("raymarch", "shear-warp", "vtk-cpu"))
    monkeypatch.setattr(cutaway, "SURFACE_MODES", ("marching-cubes",))
    monkeypatch.setattr(cutaway, "QUICK_FRAMES", 1)
    monkeypatch.setattr(cutaway, "QUICK_ROUNDS", 2)
    monkeypatch.setattr(cutaway, "MOVES", 3)
    calls = []
    real = cutaway._frame_seconds

    def recorded(item, mode, shading, size, frames, tool=None):
        calls.append((mode, shading, item.name, tool is not None))
        return real(item, mode, shading, size, frames, tool)

    monkeypatch.setattr(cutaway, "_frame_seconds", recorded)
    progress = Progress()
    files = check_written(cutaway.run(tmp_path, quick=True, progress=progress), tmp_path,
                          ["cutaway_frames.csv", "cutaway_agreement.csv", "cutaway_moves.csv", "cutaway_frames.png",
                           "cutaway.json"])
    progress.check()
    data = check_run_json(files["cutaway.json"])
    assert data["peak_rss_mib"] > 0
    # Per mode and tool, two rounds of (uncut, cut, pre-masked for ours) in that order: timed in turns.
    first = [call for call in calls if call[0] == "raymarch" and not call[1]]
    assert [(name, cut) for _, _, name, cut in first[:6]] == [("sample", False), ("sample", True),
                                                               ("pre-masked", False)] * 2
    assert not any(name == "pre-masked" for mode, _, name, _ in calls if mode == "vtk-cpu")
    _, frames = read_csv(files["cutaway_frames.csv"])
    tools = [row for row in frames if row["tool"] != "none"]
    assert {row["mode"] for row in frames} == {"raymarch", "shear-warp", "vtk-cpu"}
    assert tools and all(row["rounds"] == "2" for row in tools)
    for row in tools:
        low, high = (float(v) for v in row["ratio_to_uncut_range"].split("-"))
        assert low <= number(row, "ratio_to_uncut") <= high
        assert (row["ratio_to_premasked"] != "") == (row["ours"] == "True")
    _, agreement = read_csv(files["cutaway_agreement.csv"])
    by_mode = {row["mode"]: row for row in agreement}
    assert number(by_mode["raymarch"], "psnr_vs_premasked_db") >= 30.0
    assert number(by_mode["raymarch"], "psnr_vs_uncut_db") < number(by_mode["raymarch"], "psnr_vs_premasked_db")
    _, moves = read_csv(files["cutaway_moves.csv"])
    assert [row["moves"] for row in moves] == ["3"] * 4
