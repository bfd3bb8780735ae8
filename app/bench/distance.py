"""Benchmark: signed distance fields and CSG (source 002, chapter 3), ours against VTK in the same run, with source
002's table 3.1 beside it.

1. **Table 3.1 re-run**: exact band distances at 256^3 (quick: 128^3) for bands of 1, 5 and 10 % of the model's
   height, for the skull of 6.6 k triangles, the (filled) Stanford bunny and the 331 k-triangle marching-cubes skull
   (for the source's 346 k armadillo); the models of :mod:`app.bench.voxelise`. ``band_s`` is the band alone (the
   source's "inner loop only"), ``total_s`` with the sign (voxelisation). Source: GeForce GT 130.
2. **Full fields** with ``--outside propagate`` at 128^3, 256^3, 512^3 (quick: 64^3, 128^3) for the 100 k and
   1.09 M-triangle skulls (quick: 100 k only; 512^3 for the 100 k one only); band 2 voxels. The 1.09 M mesh is
   the marching-cubes skull of the sample CT, decimated and subdivided (no mesh of ~1 M triangles is in
   ``../shared/data/meshes/``).
3. **Errors**: our band distances against ``vtkImplicitPolyDataDistance`` at 10,000 random band voxels; the
   propagated distances against it at 10,000 random far voxels (in voxels); analytic sphere and torus.
4. **CSG**: a torus minus a sphere at 256^3 (quick: 128^3): our boolean + marching cubes (fields made), against
   manifold3d (benchmark extra; reported absent when not installed) and ``vtkLoopBooleanPolyDataFilter``: times,
   volumes, volume error against manifold3d, Hausdorff distance, watertightness.

Medians over repeats (:func:`app.pipeline.time_call`, one warm-up call first); peak resident memory of one call.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.grid import Grid
from algorithms.common.progress import ProgressCallback, report
from algorithms.common.vtk_bridge import polydata_arrays
from algorithms.references.vtk_distance import vtk_implicit_distance, vtk_loop_boolean

from ..operations.distance import mesh_field
from .common import machine_info, pyplot, save_figure, time_call, write_csv, write_json
from .voxelise import _load_average, cube_grid, peak_rss_mib, sphere_mesh, start_run, torus_mesh

#: Source 002, table 3.1: triangles and seconds for bands of 1, 5 and 10 % at 256^3 (GeForce GT 130, inner loop).
SOURCE_TABLE = {"skull 6.6k": ("schädel (skull)", 6621, (3.83, 5.4, 6.7)),
                "bunny (filled)": ("bunny", 69660, (9.00, 25.35, 42.29)),
                "skull 331k": ("armadillo", 345944, (30.49, 113.84, 198.25))}
BAND_MODELS = (("skull 6.6k", "skull6k"), ("bunny (filled)", "bunny_filled"), ("skull 331k", "skull331k"))
FULL_MODELS = (("skull 100k", "skull100k"), ("skull 1.09M", "skull1m"))
BANDS = (1.0, 5.0, 10.0)
TARGETS = {"full 256^3, 1 M triangles (s)": 10.0, "full 256^3, 100 k triangles (s)": 3.0,
           "10 % band 256^3, 346 k triangles (s)": 5.0, "propagation error (voxels)": 0.05,
           "CSG boolean + marching cubes 256^3 (s)": 0.1, "CSG volume vs manifold3d (relative)": 0.005}
SAMPLES = 10_000
#: The 512^3 full field is run for meshes up to this many triangles only (the 1.09 M one takes minutes per call).
MAX_TRIANGLES_AT_512 = 500_000


def _world(grid, flat):
    k, j, i = np.unravel_index(flat, grid.shape)
    return grid.index_to_world(np.stack([i, j, k], 1).astype(np.float64))


def _vtk_errors(points, triangles, grid, values, flat, *, seed=14) -> tuple[float, float]:
    """Largest and mean |ours - VTK| (mm) at up to 10,000 of ``flat`` voxels."""
    pick = np.random.default_rng(seed).choice(flat, min(SAMPLES, flat.size), replace=False)
    theirs, _ = vtk_implicit_distance((points, triangles), _world(grid, pick))
    error = np.abs(np.abs(values.ravel()[pick].astype(np.float64)) - np.abs(theirs))
    return float(error.max()), float(error.mean())


def _band_rows(meshes, size, repeats, progress) -> list[dict[str, Any]]:
    from algorithms.fields.distance import band_distances, band_from_percent, signed_distance

    rows = []
    models = [m for m in BAND_MODELS if m[1] in meshes]
    for n, (model, key) in enumerate(models):
        points, triangles = meshes[key]
        grid = cube_grid(points, size)
        source_name, source_triangles, source_seconds = SOURCE_TABLE[model]
        for b, percent in enumerate(BANDS):
            band_mm = band_from_percent(points, grid, percent)
            timing, band = time_call(lambda: band_distances(points, triangles, grid, band_mm), repeats=repeats)
            total, field = time_call(lambda: signed_distance(points, triangles, grid, band_mm=band_mm), repeats=1,
                                     warmup=0)
            peak = peak_rss_mib(lambda: band_distances(points, triangles, grid, band_mm))
            flat = np.flatnonzero(band.in_band.ravel())
            err_max, err_mean = _vtk_errors(points, triangles, grid, np.sqrt(band.distance2), flat)
            source = source_seconds[b] if size == 256 else ""
            rows.append({"model": model, "triangles": len(triangles), "size": size, "band_percent": percent,
                         "band_mm": band_mm, "band_s": timing.median, "band_min_s": timing.minimum,
                         "total_s": total.median, "sign_s": field.seconds["sign"], "repeats": repeats,
                         "source_model": source_name, "source_triangles": source_triangles, "source_s": source,
                         "ratio_source_to_ours": source / timing.median if source else "", "peak_rss_mib": peak,
                         "band_voxels": int(flat.size), "evaluations": band.stats["evaluations"],
                         "vtk_max_error_mm": err_max, "vtk_max_error_voxels": err_max / grid.spacing[0],
                         "vtk_mean_error_mm": err_mean})
            del band, field
        report(progress, 0.05 + 0.35 * (n + 1) / len(models))
    return rows


def _full_rows(meshes, sizes, keys, repeats, progress) -> list[dict[str, Any]]:
    from algorithms.fields.distance import signed_distance

    rows = []
    models = [m for m in FULL_MODELS if m[1] in keys]
    steps, done = len(models) * len(sizes), 0
    for model, key in models:
        points, triangles = meshes[key]
        for size in sizes:
            if size > 256 and len(triangles) > MAX_TRIANGLES_AT_512:
                rows.append({"model": model, "triangles": len(triangles), "size": size,
                             "note": "not run: over a minute per call at this size on 2 cores (see the docs)"})
                continue
            grid = cube_grid(points, size)
            band_mm = 2.0 * grid.spacing[0]
            run = lambda: signed_distance(points, triangles, grid, band_mm=band_mm, outside="propagate")  # noqa: E731
            timing, field = time_call(run, repeats=repeats if size <= 256 else 1)
            peak = peak_rss_mib(run) if size <= 256 else ""
            far = np.flatnonzero(np.abs(field.values.ravel()) > band_mm)
            err_max, err_mean = _vtk_errors(points, triangles, grid, field.values, far, seed=size)
            near = np.flatnonzero(np.abs(field.values.ravel()) <= band_mm)
            band_max, _ = _vtk_errors(points, triangles, grid, field.values, near, seed=size + 1)
            rows.append({"model": model, "triangles": len(triangles), "size": size, "band_mm": band_mm,
                         "median_s": timing.median, "min_s": timing.minimum, "repeats": len(timing.samples),
                         "sign_s": field.seconds["sign"], "band_s": field.seconds["band"],
                         "outside_s": field.seconds["outside"], "peak_rss_mib": peak,
                         "far_max_error_voxels": err_max / grid.spacing[0],
                         "far_mean_error_voxels": err_mean / grid.spacing[0],
                         "band_max_error_voxels": band_max / grid.spacing[0],
                         "levels": field.stats.get("levels", 1),
                         **{f"outside_{k}_s": v for k, v in field.stats.get("propagation_seconds", {}).items()}})
            del field
            done += 1
            report(progress, 0.4 + 0.35 * done / steps)
    return rows


def _analytic_rows(size) -> list[dict[str, Any]]:
    from algorithms.fields.distance import signed_distance

    rows = []
    shapes = {"sphere r 40": (sphere_mesh(40.0, 512, 256), lambda x: np.linalg.norm(x, axis=1) - 40.0),
              "torus 45/15": (torus_mesh(45.0, 15.0, 512, 256),
                              lambda x: np.hypot(np.hypot(x[:, 0], x[:, 1]) - 45.0, x[:, 2]) - 15.0)}
    for name, ((points, triangles), sdf) in shapes.items():
        grid = cube_grid(points, size)
        field = signed_distance(points, triangles, grid, band_mm=3 * grid.spacing[0], outside="propagate")
        flat = np.random.default_rng(3).choice(grid.size, SAMPLES, replace=False)
        error = np.abs(field.values.ravel()[flat] - sdf(_world(grid, flat)))
        stray = float(np.abs(sdf(points[triangles].mean(axis=1))).max())
        rows.append({"shape": name, "size": size, "triangles": len(triangles), "max_error_mm": float(error.max()),
                     "max_error_voxels": float(error.max() / grid.spacing[0]), "mesh_stray_mm": stray,
                     "seconds": field.seconds["total"]})
    return rows


def _manifold(points, triangles):
    import manifold3d

    mesh = manifold3d.Mesh(vert_properties=np.ascontiguousarray(points, np.float32),
                           tri_verts=np.ascontiguousarray(triangles, np.uint32))
    return manifold3d.Manifold(mesh)


def _csg_rows(size, repeats) -> list[dict[str, Any]]:
    from algorithms.compare.measures import enclosed_volume, hausdorff
    from algorithms.compare.topology import edge_manifoldness
    from algorithms.fields.csg import combine

    from algorithms.fields.distance import signed_distance

    torus = torus_mesh(30.0, 10.0, 512, 256)
    ball = sphere_mesh(14.0, 256, 128)
    ball = (ball[0] + np.array([30.0, 0.0, 0.0]), ball[1])
    grid = Grid.around((-42, 42, -42, 42, -42, 42), voxels=size, padding=2)
    ft = signed_distance(*torus, grid, band_mm=3 * grid.spacing[0]).values
    fs = signed_distance(*ball, grid, band_mm=3 * grid.spacing[0]).values
    boolean, field = time_call(lambda: combine([ft, fs], "difference"), repeats=repeats)
    meshing, ours = time_call(lambda: mesh_field(field, grid), repeats=repeats)
    both, _ = time_call(lambda: mesh_field(combine([ft, fs], "difference"), grid), repeats=repeats)
    # the marching cubes core alone, on the array mesh_field hands it (negated, padded by one voxel)
    from algorithms.surfaces.marching_cubes import marching_cubes

    padded = np.pad(np.negative(field), 1, constant_values=np.float32(-float(field.max()) - 1.0))
    core, _ = time_call(lambda: marching_cubes(padded, 0.0, spacing=grid.spacing), repeats=repeats)
    rows = []
    surfaces = []

    def row(method, seconds, points, triangles, extra=None):
        surfaces.append((points, triangles))
        edges = edge_manifoldness(points, triangles)
        rows.append({"method": method, "size": size, "seconds": seconds, "triangles": len(triangles),
                     "volume_mm3": float(enclosed_volume(points, triangles)), "watertight": edges.watertight,
                     "boundary_edges": edges.boundary_edges, **(extra or {})})

    row("ours (boolean + marching cubes)", both.median, ours.points, ours.triangles,
        {"boolean_s": boolean.median, "meshing_s": meshing.median, "marching_cubes_core_s": core.median})
    reference = None
    try:
        start = time.perf_counter()
        result = _manifold(*torus) - _manifold(*ball)
        seconds = time.perf_counter() - start
        mesh = result.to_mesh()
        reference = (np.asarray(mesh.vert_properties[:, :3], np.float64), np.asarray(mesh.tri_verts, np.int64))
        row("manifold3d", seconds, *reference)
    except ImportError:
        rows.append({"method": "manifold3d (not installed: pip install manifold3d)", "size": size})
    loop, seconds = vtk_loop_boolean(torus, ball, "difference")
    loop_arrays = polydata_arrays(loop) if loop.GetNumberOfCells() else (np.empty((0, 3)), np.empty((0, 3), int))
    row("vtkLoopBooleanPolyDataFilter", seconds, np.asarray(loop_arrays[0], np.float64),
        np.asarray(loop_arrays[1], np.int64))
    if reference is not None:
        volume = rows[1]["volume_mm3"]
        for r, surface in zip([r for r in rows if "volume_mm3" in r], surfaces):
            if r["triangles"]:
                r["volume_error_vs_manifold3d"] = (r["volume_mm3"] - volume) / volume
                r["hausdorff_vs_manifold3d_mm"] = hausdorff(surface, reference).hausdorff
    return rows


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Run every part (see the module notes); write CSV files, a plot and JSON to ``out_dir``."""
    out_dir, load_at_start, meshes = start_run(out_dir)
    report(progress, 0.05)
    # each part is written as soon as it is measured (a long run stopped midway keeps what it measured)
    csg = _csg_rows(128 if quick else 256, 3 if quick else 5)
    written = [write_csv(out_dir / "distance_csg.csv", csg)]
    analytic = _analytic_rows(64 if quick else 128)
    written.append(write_csv(out_dir / "distance_analytic.csv", analytic))
    band_size = 128 if quick else 256
    band = _band_rows(meshes, band_size, 1 if quick else 3, progress)
    written.append(write_csv(out_dir / "distance_band.csv", band))
    sizes = (64, 128) if quick else (128, 256, 512)
    full = _full_rows(meshes, sizes, ("skull100k",) if quick else ("skull100k", "skull1m"), 1 if quick else 3,
                      progress)
    written += [write_csv(out_dir / "distance_full.csv", full), _plot(band, full, out_dir / "distance.png")]
    info = machine_info()
    info["load_average_at_start_and_end"] = [load_at_start, _load_average()]
    written.append(write_json(out_dir / "distance.json", {
        "benchmark": "distance", "quick": quick, "machine": info, "targets": TARGETS,
        "source_table_3_1": {k: {"model": v[0], "triangles": v[1], "seconds_1_5_10_percent": list(v[2])}
                             for k, v in SOURCE_TABLE.items()},
        "band": band, "full": full, "analytic": analytic, "csg": csg, "notes": __doc__}))
    report(progress, 1.0)
    return written


def _plot(band, full, path: Path) -> Path:
    plt = pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    for model in dict.fromkeys(r["model"] for r in band):
        rows = [r for r in band if r["model"] == model]
        left.plot([r["band_percent"] for r in rows], [r["band_s"] for r in rows], "o-", label=f"ours, {model}")
        if rows[0]["source_s"] != "":
            left.plot([r["band_percent"] for r in rows], [r["source_s"] for r in rows], "x--",
                      label=f"source 002 (GPU), {rows[0]['source_model']}")
    left.set(xlabel="band (% of model height)", ylabel="seconds", yscale="log",
             title=f"exact band at {band[0]['size'] if band else ''}^3")
    left.legend(fontsize=7)
    for model in dict.fromkeys(r["model"] for r in full):
        rows = [r for r in full if r["model"] == model and "median_s" in r]
        right.plot([r["size"] for r in rows], [r["median_s"] for r in rows], "o-", label=model)
    right.set(xlabel="grid size n (n^3 voxels)", ylabel="seconds (median)", yscale="log",
              title="full field, propagated")
    right.legend(fontsize=7)
    figure.tight_layout()
    return save_figure(figure, path)
