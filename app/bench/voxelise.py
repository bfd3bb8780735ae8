"""Benchmark: mesh voxelisation, ours against VTK's stencil in the same run, with source 002's table 2.1 beside it.

Source 002 (section 2.2, table 2.1) voxelised five models on the GPU (Core 2 Duo 2.93 GHz, GeForce GT 130, OpenGL
2.0) at 64^3, 128^3 and 256^3. The same kinds of models here:

- ``torus 80``: a torus of 80 triangles (8 x 5 quads), made in code;
- ``skull 6.6k``: the sample CT's marching-cubes skull (300 HU, padded so it closes) decimated to 6,620 triangles
  (``vtkQuadricDecimation``, checked closed), for the source's 6,621-triangle skull;
- ``bunny (filled)``: the Stanford bunny of the shared meshes, its five holes closed by ``vtkFillHolesFilter``
  (which leaves 18 boundary edges of the largest hole open and meets the bunny with the opposite orientation
  along 215 edges; fans over that chain close it), by parity; and ``bunny (holes, winding)``: the bunny as
  scanned, by the winding-number rule (VTK's column is then the stencil of the filled bunny, the solid the user
  expects);
- ``skull 100k``: the skull decimated to 100,000 triangles (the issue's 100 k-triangle case);
- ``skull 331k``: the full marching-cubes skull, 330,872 triangles, for the source's armadillo (345,944);
- ``skull 1.09M``: the skull decimated to 271,928 triangles and subdivided once (``vtkLinearSubdivisionFilter``):
  1,087,712 triangles, for the source's happy Buddha (1,087,716).

Each at 64^3, 128^3, 256^3 and 512^3 (quick: 64^3 and 128^3): a cubic grid of n^3 voxels with the model centred and
its longest side spanning n - 3 voxels, as the source fits each model into its view volume. The meshes are built
once and cached in ``DIR/meshes`` (the decimations take a while).

Measured
--------
- ``median_s``/``min_s``: wall time of ``voxelise(points, triangles, grid)`` (ours: the index transform, bucketing,
  row crossings and filling, numba threads) and of ``vtkPolyDataToImageStencil`` + ``vtkImageStencilToImage``
  (VTK: the mesh was moved into the grid's frame beforehand; tolerance 0) over ``repeats`` calls after one untimed
  warm-up; ``first_call_s``: our first call in this process (loading the compiled kernels from numba's cache).
- ``ratio_vtk_to_ours`` = VTK's median / ours, ``source_s`` and ``ratio_source_to_ours`` = table 2.1's time / ours.
- ``peak_rss_mib``: the rise of the process's resident set during one more call (the kernel's high-water mark,
  reset through ``/proc/self/clear_refs`` before it): everything counts, numba's and VTK's C++ allocations too.
- Agreement with VTK on the same grid: IoU and differing voxels (``voxelise_agreement.csv``); the voxel volume of
  a fine torus and sphere against their analytic volumes (``voxelise_analytic.csv``); IoU and differing voxels on
  the real closed meshes (spot, cow, fandisk, scaled to 150 mm) and a sphere and torus at 64^3 and 256^3, on an
  anisotropic 0.5 x 0.5 x 2 mm grid and on a rotated anisotropic grid (``voxelise_grids.csv``).
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.grid import Grid
from algorithms.common.progress import ProgressCallback, report
from algorithms.common.vtk_bridge import polydata_arrays, polydata_from_arrays, run_algorithm
from algorithms.references.vtk_fields import vtk_stencil_mask, StencilPipeline

from ..io import load_volume
from ..io.meshes import load_mesh
from ..samples import sample_path
from ..vtk_setup import configure_vtk, smp_backend
from .common import machine_info, pyplot, save_figure, time_call, write_csv, write_json

MESHES = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "meshes"
SIZES = (64, 128, 256, 512)
QUICK_SIZES = (64, 128)
#: Source 002, table 2.1: model -> (triangles, seconds at 64^3, 128^3, 256^3).
SOURCE_TABLE = {"torus": (80, (0.06, 0.11, 0.33)), "schädel (skull)": (6621, (0.07, 0.12, 0.34)),
                "bunny": (69660, (0.11, 0.18, 0.46)), "armadillo": (345944, (0.39, 0.75, 1.72)),
                "happy buddha": (1087716, (1.2, 2.31, 4.73))}
#: Our models: name, cache key, source row, inside rule.
MODELS = (("torus 80", "torus80", "torus", "parity"), ("skull 6.6k", "skull6k", "schädel (skull)", "parity"),
          ("bunny (filled)", "bunny_filled", "bunny", "parity"),
          ("bunny (holes, winding)", "bunny", "bunny", "winding"),
          ("skull 100k", "skull100k", None, "parity"), ("skull 331k", "skull331k", "armadillo", "parity"),
          ("skull 1.09M", "skull1m", "happy buddha", "parity"))
TIME_COLUMNS = ("model", "triangles", "rule", "size", "voxels", "method", "median_s", "min_s", "repeats",
                "ratio_vtk_to_ours", "source_s", "ratio_source_to_ours", "peak_rss_mib", "inside_voxels",
                "first_call_s")
AGREEMENT_COLUMNS = ("model", "size", "iou", "differing_voxels", "ours_inside", "vtk_inside", "vtk_reference")
ANALYTIC_COLUMNS = ("shape", "size", "analytic_mm3", "mesh_mm3", "ours_mm3", "ours_error", "vtk_mm3", "vtk_error")


# -- meshes ----------------------------------------------------------------------------------------------------
def torus_mesh(ring: float, tube: float, around: int, across: int):
    """A closed torus around z (``around x across`` quads as triangle pairs), facing out."""
    u = 2 * np.pi * np.arange(around) / around
    v = 2 * np.pi * np.arange(across) / across
    uu, vv = np.meshgrid(u, v, indexing="ij")
    radius = ring + tube * np.cos(vv)
    points = np.stack([radius * np.cos(uu), radius * np.sin(uu), tube * np.sin(vv)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(around), np.arange(across), indexing="ij")
    a, b = i * across + j, ((i + 1) % around) * across + j
    c, d = ((i + 1) % around) * across + (j + 1) % across, i * across + (j + 1) % across
    triangles = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return points, triangles.astype(np.int64)


def sphere_mesh(radius: float, around: int, across: int):
    """A closed UV sphere (single-point poles), facing out."""
    theta = np.pi * np.arange(1, across) / across
    phi = 2 * np.pi * np.arange(around) / around
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1).reshape(-1, 3)
    points = np.concatenate([[[0, 0, 1]], ring, [[0, 0, -1]]]) * radius
    index = 1 + np.arange((across - 1) * around).reshape(across - 1, around)
    following = np.roll(index, -1, axis=1)
    parts = [np.stack([np.zeros(around, np.int64), index[0], following[0]], 1)]
    for r in range(across - 2):
        parts += [np.stack([index[r], index[r + 1], following[r + 1]], 1),
                  np.stack([index[r], following[r + 1], following[r]], 1)]
    parts.append(np.stack([np.full(around, len(points) - 1), following[-1], index[-1]], 1))
    return points, np.concatenate(parts).astype(np.int64)


def _polydata_arrays(polydata):
    points, triangles = polydata_arrays(polydata)
    return np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(triangles, dtype=np.int64)


def _skull():
    """The sample CT's bone surface at 300 HU by our marching cubes, padded with air so it closes; LPS mm."""
    from algorithms.surfaces.marching_cubes import marching_cubes

    from ..meshing import closed_at_edges

    volume = closed_at_edges(load_volume(sample_path("ct")), 300.0)
    mesh = marching_cubes(volume.array, 300.0, spacing=volume.spacing, normals=False)
    points = np.asarray(mesh.points, dtype=np.float64) @ volume.direction.T + np.asarray(volume.origin)
    return points, np.asarray(mesh.triangles, dtype=np.int64)


def _decimated(mesh, triangles: int):
    from vtkmodules.vtkFiltersCore import vtkQuadricDecimation

    decimate = vtkQuadricDecimation()
    decimate.SetInputData(polydata_from_arrays(*mesh))
    decimate.SetTargetReduction(1.0 - triangles / len(mesh[1]))
    decimate.VolumePreservationOn()
    return _polydata_arrays(run_algorithm(decimate))


def _subdivided(mesh):
    from vtkmodules.vtkFiltersModeling import vtkLinearSubdivisionFilter

    subdivide = vtkLinearSubdivisionFilter()
    subdivide.SetInputData(polydata_from_arrays(*mesh))
    subdivide.SetNumberOfSubdivisions(1)
    return _polydata_arrays(run_algorithm(subdivide))


def _bunny(filled: bool):
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData, vtkTriangleFilter
    from vtkmodules.vtkFiltersModeling import vtkFillHolesFilter

    mesh = load_mesh(MESHES / "stanford-bunny.obj.gz")
    if not filled:
        return mesh.points, mesh.triangles
    fill = vtkFillHolesFilter()
    fill.SetInputData(mesh.polydata)
    fill.SetHoleSize(1e6)
    triangulate = vtkTriangleFilter()
    triangulate.SetInputConnection(fill.GetOutputPort())
    clean = vtkCleanPolyData()
    clean.SetInputConnection(triangulate.GetOutputPort())
    return close_by_fans(*_polydata_arrays(run_algorithm(clean)))


def close_by_fans(points, triangles):
    """The mesh with a fan over every hole that is left (``vtkFillHolesFilter`` leaves the bunny's largest,
    non-planar hole partly open: 18 boundary edges), so it is closed."""
    from algorithms.fields.winding import boundary_caps

    caps = boundary_caps(points, triangles)
    if caps.count == 0:
        return points, triangles
    return caps.points, np.concatenate([triangles, caps.triangles])


def build_meshes(folder: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every model of :data:`MODELS`, built once and cached in ``folder`` as ``.npz``; checked closed (the bunny
    with holes aside)."""
    from algorithms.compare.topology import edge_manifoldness

    folder.mkdir(parents=True, exist_ok=True)
    meshes: dict[str, Any] = {}

    def cached(key, build):
        path = folder / f"{key}.npz"
        if path.exists():
            data = np.load(path)
            meshes[key] = (data["points"], data["triangles"])
        else:
            meshes[key] = build()
            np.savez(path, points=meshes[key][0], triangles=meshes[key][1])
        return meshes[key]

    cached("torus80", lambda: torus_mesh(40.0, 15.0, 8, 5))
    skull = cached("skull331k", _skull)
    cached("skull6k", lambda: _decimated(skull, 6620))
    cached("skull100k", lambda: _decimated(skull, 100_000))
    cached("skull1m", lambda: _subdivided(_decimated(skull, 271_928)))
    if (MESHES / "stanford-bunny.obj.gz").exists():
        cached("bunny", lambda: _bunny(False))
        cached("bunny_filled", lambda: _bunny(True))
    for key, (points, triangles) in meshes.items():
        if key != "bunny" and not edge_manifoldness(points, triangles).watertight:
            raise RuntimeError(f"the benchmark mesh {key} is not closed; delete {folder} and run again")
    return meshes


# -- measuring ---------------------------------------------------------------------------------------------------
def cube_grid(points: np.ndarray, n: int) -> Grid:
    """``n^3`` cubic voxels around the mesh, centred, its longest side spanning ``n - 3`` voxels."""
    low, high = points.min(axis=0), points.max(axis=0)
    step = float((high - low).max()) / (n - 3)
    origin = (low + high) / 2 - step * (n - 1) / 2
    return Grid((n, n, n), (step, step, step), tuple(origin))


def _status(key: str) -> int:
    with open("/proc/self/status") as handle:
        return next(int(line.split()[1]) for line in handle if line.startswith(key))


def peak_rss_mib(function) -> float | str:
    """How far the resident set rose during one call (MiB), from the kernel's high-water mark; "" where the
    mark cannot be reset."""
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
        start = _status("VmRSS:")
        function()
        return (_status("VmHWM:") - start) / 1024
    except OSError:
        return ""


def _repeats(size: int, quick: bool) -> int:
    if quick:
        return 2
    return 5 if size <= 256 else 3


def _agreement(model, size, ours, theirs, reference) -> dict[str, Any]:
    both = int(np.count_nonzero(ours & theirs))
    either = int(np.count_nonzero(ours | theirs))
    return {"model": model, "size": size, "iou": both / either if either else 1.0,
            "differing_voxels": int(np.count_nonzero(ours != theirs)), "ours_inside": int(np.count_nonzero(ours)),
            "vtk_inside": int(np.count_nonzero(theirs)), "vtk_reference": reference}


def _analytic_rows(sizes) -> list[dict[str, Any]]:
    from algorithms.compare.measures import enclosed_volume
    from algorithms.fields.voxelise import voxelise

    shapes = (("sphere r 40 mm", sphere_mesh(40.0, 720, 360), 4.0 / 3.0 * math.pi * 40.0 ** 3),
              ("torus R 45 r 15 mm", torus_mesh(45.0, 15.0, 720, 360), 2 * math.pi ** 2 * 45.0 * 15.0 ** 2))
    rows = []
    for name, (points, triangles), analytic in shapes:
        mesh_volume = abs(float(enclosed_volume(points, triangles)))
        for size in sizes:
            grid = Grid.around(np.ravel(np.column_stack([points.min(0), points.max(0)])), voxels=size)
            ours = float(np.count_nonzero(voxelise(points, triangles, grid))) * grid.voxel_volume
            vtk = float(np.count_nonzero(vtk_stencil_mask((points, triangles), grid))) * grid.voxel_volume
            rows.append({"shape": name, "size": size, "analytic_mm3": analytic, "mesh_mm3": mesh_volume,
                         "ours_mm3": ours, "ours_error": (ours - analytic) / analytic, "vtk_mm3": vtk,
                         "vtk_error": (vtk - analytic) / analytic})
    return rows


#: The real closed meshes of the shared folder (scaled so their longest side is this many mm).
REAL_CLOSED = ("spot", "cow", "fandisk")
REAL_SIZE_MM = 150.0
GRID_COLUMNS = ("mesh", "triangles", "grid", "dimensions", "spacing_mm", "iou", "differing_voxels", "ours_inside",
                "vtk_inside")


def rotated_grid(points: np.ndarray, spacing=(0.7, 0.9, 1.3), axis=(1.0, 2.0, 3.0), degrees: float = 37.0) -> Grid:
    """An anisotropic grid rotated by ``degrees`` about ``axis``, around the mesh in its own frame (2 voxels of
    margin)."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = math.radians(degrees)
    direction = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k
    spacing = np.asarray(spacing, dtype=np.float64)
    local = points @ direction
    first = np.floor(local.min(axis=0) / spacing) - 2
    last = np.ceil(local.max(axis=0) / spacing) + 2
    return Grid(tuple(int(n) for n in last - first + 1), tuple(spacing), tuple(direction @ (first * spacing)),
                tuple(direction.ravel()))


def _grid_rows(quick: bool) -> list[dict[str, Any]]:
    """IoU and differing voxels against VTK's stencil on the real closed meshes and a fine sphere and torus, at
    64^3 and 256^3 (quick: 64^3), on an anisotropic 0.5 x 0.5 x 2 mm grid and a rotated anisotropic grid."""
    from algorithms.fields.voxelise import voxelise

    meshes = [("sphere r 40 mm", sphere_mesh(40.0, 360, 180)),
              ("torus R 45 r 15 mm", torus_mesh(45.0, 15.0, 360, 180))]
    for name in REAL_CLOSED:
        path = MESHES / f"{name}.obj.gz"
        if path.exists():
            mesh = load_mesh(path)
            points = np.asarray(mesh.points, dtype=np.float64)
            low, high = points.min(axis=0), points.max(axis=0)
            meshes.append((name, ((points - (low + high) / 2) * (REAL_SIZE_MM / (high - low).max()),
                                  np.asarray(mesh.triangles, dtype=np.int64))))
    rows = []
    for name, (points, triangles) in meshes:
        bounds = np.ravel(np.column_stack([points.min(axis=0), points.max(axis=0)]))
        sizes = (64,) if quick else (64, 256)
        grids = [(f"{n} along the longest side", Grid.around(bounds, voxels=n)) for n in sizes]
        if not quick:
            grids += [("anisotropic 0.5 x 0.5 x 2 mm", Grid.around(bounds, spacing=(0.5, 0.5, 2.0))),
                      ("rotated 37 deg, 0.7 x 0.9 x 1.3 mm", rotated_grid(points))]
        for label, grid in grids:
            ours = voxelise(points, triangles, grid)
            theirs = vtk_stencil_mask((points, triangles), grid)
            both, either = int(np.count_nonzero(ours & theirs)), int(np.count_nonzero(ours | theirs))
            rows.append({"mesh": name, "triangles": len(triangles), "grid": label,
                         "dimensions": "x".join(map(str, grid.dimensions)),
                         "spacing_mm": " x ".join(f"{s:.4g}" for s in grid.spacing),
                         "iou": both / either if either else 1.0,
                         "differing_voxels": int(np.count_nonzero(ours != theirs)),
                         "ours_inside": int(np.count_nonzero(ours)), "vtk_inside": int(np.count_nonzero(theirs))})
    return rows


def start_run(out_dir) -> tuple[Path, list[float] | None, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """What the field benchmarks do first: VTK configured, the load average noted, the output folder made and the
    test meshes built in it. Returns ``(out_dir, load average at the start, meshes)``."""
    configure_vtk()
    load_at_start = _load_average()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return out_dir, load_at_start, build_meshes(out_dir / "meshes")


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Time ours and VTK's stencil on every model and size; write CSV files, plots and JSON to ``out_dir``."""
    from algorithms.fields.voxelise import voxelise

    out_dir, load_at_start, meshes = start_run(out_dir)
    sizes = QUICK_SIZES if quick else SIZES
    models = [model for model in MODELS if model[1] in meshes]
    skipped = [model[0] for model in MODELS if model[1] not in meshes]
    report(progress, 0.05)
    times: list[dict[str, Any]] = []
    agreement: list[dict[str, Any]] = []
    steps, done = len(models) * len(sizes), 0
    for model, key, source_row, rule in models:
        points, triangles = meshes[key]
        reference_key = "bunny_filled" if key == "bunny" else key
        first_call: float | str = ""
        for size in sizes:
            grid = cube_grid(points, size)
            repeats = _repeats(size, quick)
            base = {"model": model, "triangles": len(triangles), "rule": rule, "size": size, "voxels": grid.size,
                    "repeats": repeats}
            if first_call == "":
                start = time.perf_counter()
                voxelise(points, triangles, grid, inside=rule)
                first_call = time.perf_counter() - start
            timing, ours = time_call(lambda: voxelise(points, triangles, grid, inside=rule), repeats=repeats)
            ours_peak = peak_rss_mib(lambda: voxelise(points, triangles, grid, inside=rule))
            pipeline = StencilPipeline(meshes[reference_key], grid)
            vtk_timing, theirs = time_call(pipeline.run, repeats=repeats)
            theirs = np.array(theirs)
            del pipeline
            vtk_peak = peak_rss_mib(lambda: StencilPipeline(meshes[reference_key], grid).run())
            source = SOURCE_TABLE[source_row][1][(64, 128, 256).index(size)] if source_row and size <= 256 else ""
            times.append({**base, "method": "ours", "median_s": timing.median, "min_s": timing.minimum,
                          "ratio_vtk_to_ours": vtk_timing.median / timing.median, "source_s": source,
                          "ratio_source_to_ours": source / timing.median if source != "" else "",
                          "peak_rss_mib": ours_peak, "inside_voxels": int(np.count_nonzero(ours)),
                          "first_call_s": first_call if size == sizes[0] else ""})
            times.append({**base, "method": "vtk stencil" + (" (filled bunny)" if key == "bunny" else ""),
                          "median_s": vtk_timing.median, "min_s": vtk_timing.minimum, "ratio_vtk_to_ours": "",
                          "peak_rss_mib": vtk_peak, "inside_voxels": int(np.count_nonzero(theirs))})
            reference = "stencil of the filled bunny" if key == "bunny" else "stencil of the same mesh"
            agreement.append(_agreement(model, size, ours, theirs, reference))
            del ours, theirs
            done += 1
            report(progress, 0.05 + 0.8 * done / steps)
    analytic = _analytic_rows(sizes)
    report(progress, 0.9)
    grids = _grid_rows(quick)
    report(progress, 0.95)
    written = [write_csv(out_dir / "voxelise_times.csv", times, TIME_COLUMNS),
               write_csv(out_dir / "voxelise_agreement.csv", agreement, AGREEMENT_COLUMNS),
               write_csv(out_dir / "voxelise_analytic.csv", analytic, ANALYTIC_COLUMNS),
               write_csv(out_dir / "voxelise_grids.csv", grids, GRID_COLUMNS),
               _plot(times, sizes, out_dir / "voxelise.png")]
    info = machine_info()
    info["vtk_smp_backend"] = smp_backend()
    info["numba_threading_layer"] = _threading_layer()
    info["load_average_at_start_and_end"] = [load_at_start, _load_average()]
    written.append(write_json(out_dir / "voxelise.json", {
        "benchmark": "voxelise", "quick": quick, "machine": info, "sizes": list(sizes),
        "source_table_2_1": {name: {"triangles": count, "seconds_64_128_256": list(seconds)}
                             for name, (count, seconds) in SOURCE_TABLE.items()},
        "skipped_models": skipped, "targets": _targets(times), "notes": __doc__,
        "times": times, "agreement": agreement, "analytic": analytic, "grids": grids,
    }))
    report(progress, 1.0)
    return written


def _load_average() -> list[float] | None:
    """The machine's 1, 5 and 15 minute load averages (other work on a shared machine slows every timing)."""
    try:
        return [round(value, 2) for value in os.getloadavg()]
    except OSError:
        return None


def _threading_layer() -> str:
    import numba

    try:
        return numba.threading_layer()
    except ValueError:  # no parallel kernel has run
        return "not started"


def _targets(times: list[dict[str, Any]]) -> dict[str, Any]:
    """The issue's speed targets against this run's medians (ours)."""
    def median(model, size):
        return next((row["median_s"] for row in times if row["method"] == "ours" and row["model"] == model
                     and row["size"] == size), None)

    at_512 = [row["median_s"] for row in times if row["method"] == "ours" and row["size"] == 512]
    return {"skull 1.09M at 256^3 (target <= 0.8 s)": median("skull 1.09M", 256),
            "skull 100k at 256^3 (target <= 0.1 s)": median("skull 100k", 256),
            "slowest model at 512^3 (target <= 3 s)": max(at_512) if at_512 else None}


def _plot(times: list[dict[str, Any]], sizes, path: Path) -> Path:
    plt = pyplot()
    models = list(dict.fromkeys(row["model"] for row in times))
    figure, axes = plt.subplots(1, 2, figsize=(13, 5))
    colours = plt.get_cmap("tab10")
    for index, model in enumerate(models):
        colour = colours(index % 10)
        for method, style in (("ours", "-o"), ("vtk", "--s")):
            rows = [r for r in times if r["model"] == model and r["method"].startswith(method)]
            axes[0].plot([r["size"] for r in rows], [r["median_s"] for r in rows], style, color=colour,
                         label=f"{model}, {'ours' if method == 'ours' else 'VTK stencil'}", markersize=4)
        source = [r for r in times if r["model"] == model and r["method"] == "ours" and r["source_s"] != ""]
        if source and model != "bunny (holes, winding)":
            axes[0].plot([r["size"] for r in source], [r["source_s"] for r in source], ":^", color=colour,
                         markersize=4, label=f"{model}, source 002 (GPU)")
        ours = [r for r in times if r["model"] == model and r["method"] == "ours"]
        axes[1].plot([r["size"] for r in ours], [r["ratio_vtk_to_ours"] for r in ours], "-o", color=colour,
                     label=model, markersize=4)
    for axis in axes:
        axis.set_xscale("log", base=2)
        axis.set_xticks(list(sizes), [f"{n}^3" for n in sizes])
        axis.set_xlabel("grid (voxels)")
        axis.grid(True, which="both", alpha=0.3)
    axes[0].set_yscale("log")
    axes[0].set_ylabel("median time (s)")
    axes[0].set_title("Voxelisation time: ours, VTK's stencil, source 002's table 2.1")
    axes[0].legend(fontsize=6, ncol=2)
    axes[1].set_yscale("log")
    axes[1].set_ylabel("VTK median / our median")
    axes[1].set_title("Speed-up over vtkPolyDataToImageStencil (same run)")
    axes[1].legend(fontsize=7)
    return save_figure(figure, path)
