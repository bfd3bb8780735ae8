"""Benchmark: our isosurface stuffing against VTK's tetrahedralisations, in the same run.

Cases
-----
- The sample CT's skull (the FORBILD head, 512 x 512 x 176, 0.547 x 0.547 x 1.5 mm, int16 HU; quick: the same head on
  256 x 256 x 88 voxels) at 300 HU, lattice spacings h = 4.3, 2.85
  and 1.73 mm (about source 002's three sizes: 106,392 / 365,976 / 1,648,902 tetrahedra in 0.16 / 0.55 / 2.42 s on
  2009 hardware, listed beside ours) and h = 2, 1.5, 1, 0.7 mm (quick: 4.3, 2.85, 1.73, 1.5).
- Analytic solids sampled on 1 mm grids (float32): a sphere of radius 40 mm and a torus (radii 40 and 15 mm) in a
  124^3 grid at h = 2 and 1 mm, with their exact volumes.
- VTK: ``vtkDelaunay3D`` on the flying-edges isosurface's points (tetrahedra outside removed by the field at their
  centroids) and ``vtkClipVolume`` (tetrahedra only), once per volume (they have no h). TetGen and fTetWild
  (``tetgen``, ``pytetwild``, the ``bench`` extra) are not run yet: the JSON says whether they are installed.

Measured
--------
- ``median_s``: wall time, median over repeats after one warm-up, of the whole method: for stuffing the field,
  cuts, warp, stencils and the output mesh (``field_s``... the breakdown, medians too); for VTK the filter and,
  for Delaunay, the surface and the removal of the outside tetrahedra. ``cpu_s``: the process's CPU seconds per
  run (all threads, median), which the other users of a shared machine inflate much less than the wall time; the
  load average at the start and end of the run is in the JSON.
- quality: dihedral-angle range, fraction of tetrahedra with an angle under 10 degrees, volume against the
  marching-cubes (flying edges, on the volume padded with its minimum so the surface is closed) enclosed volume,
  boundary fidelity: the fraction of the flying-edges surface's vertices within 0.5 voxel (the smallest spacing)
  and within 1 mm of the mesh's boundary, and the largest such distance.
- ``peak_mb``: peak of Python-tracked allocations (tracemalloc: NumPy arrays) during one run of ours; the process's
  maximum resident size is in the JSON. ``bytes_per_lattice_point`` against source 002's 44.
"""

from __future__ import annotations

import importlib.util
import os
import resource
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.progress import ProgressCallback, report
from algorithms.common.vtk_bridge import image_from_array
from algorithms.references.vtk_surfaces import contour
from algorithms.references.vtk_tetrahedra import vtk_clip_tetrahedra, vtk_delaunay_tetrahedra

from ..vtk_setup import configure_vtk
from .common import ct_volume, machine_info, pyplot, save_figure, time_call, write_csv, write_json

SOURCE_002 = [{"tetrahedra": 106_392, "seconds": 0.16}, {"tetrahedra": 365_976, "seconds": 0.55},
              {"tetrahedra": 1_648_902, "seconds": 2.42}]
CT_H = (4.3, 2.85, 2.0, 1.73, 1.5, 1.0, 0.7)
QUICK_CT_H = (4.3, 2.85, 1.73, 1.5)
COLUMNS = ("dataset", "method", "h_mm", "tetrahedra", "points", "median_s", "min_s", "repeats", "field_s", "cut_s",
           "warp_s", "stencil_s", "output_s", "cpu_s", "ratio_to_ours", "min_dihedral_deg", "max_dihedral_deg",
           "under_10_deg",
           "volume_mm3", "reference_volume_mm3", "volume_error_pct", "within_half_voxel", "within_1mm",
           "max_distance_mm", "peak_mb", "bytes_per_lattice_point")


def _datasets(quick: bool):
    ct = ct_volume(quick)
    yield "CT skull 300 HU", ct.array, ct.spacing, ct.origin, 300.0, QUICK_CT_H if quick else CT_H, None
    n = 124  # the torus reaches 55 mm from the centre
    axis = np.arange(n, dtype=np.float32) - (n - 1) / 2.0
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    sphere = (40.0 - np.sqrt(x * x + y * y + z * z)).astype(np.float32)
    yield "sphere r 40 mm", sphere, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 0.0, (2.0, 1.0), 4.0 / 3.0 * np.pi * 40.0 ** 3
    ring = np.sqrt(x * x + y * y) - 40.0
    torus = (15.0 - np.sqrt(ring * ring + z * z)).astype(np.float32)
    yield "torus 40/15 mm", torus, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 0.0, (2.0, 1.0), 2 * np.pi ** 2 * 40 * 15 ** 2
    del x, y, z


def _reference_surface(array, spacing, origin, iso):
    """Flying edges on the volume padded by one sample of its minimum (a closed surface), volume frame."""
    from algorithms.compare.triangles import surface_arrays

    padded = np.pad(array, 1, constant_values=array.min())
    shifted = np.asarray(origin) - np.asarray(spacing)
    return surface_arrays(contour(image_from_array(padded, spacing, shifted), iso, normals=False))


def _quality(mesh, boundary, surface, spacing, reference_volume) -> dict[str, Any]:
    from algorithms.compare.measures import enclosed_volume
    from algorithms.compare.tet_quality import boundary_faces, boundary_fidelity, quality_report

    q = quality_report(mesh.points, mesh.tetrahedra, with_conformity=False)
    surface_volume = enclosed_volume(surface)
    reference_volume = reference_volume if reference_volume is not None else surface_volume
    if boundary is None:
        boundary = boundary_faces(mesh.tetrahedra)
    half = 0.5 * float(min(spacing))
    fidelity = boundary_fidelity(surface[0], mesh.points, boundary, within=(half, 1.0))
    return {
        "min_dihedral_deg": q["min_dihedral_deg"], "max_dihedral_deg": q["max_dihedral_deg"],
        "under_10_deg": q["under_10_deg"], "volume_mm3": q["volume_mm3"], "reference_volume_mm3": reference_volume,
        "marching_cubes_volume_mm3": surface_volume,
        "volume_error_pct": 100.0 * (q["volume_mm3"] - reference_volume) / reference_volume,
        "within_half_voxel": fidelity["within_mm"][f"{half:g}"], "within_1mm": fidelity["within_mm"]["1"],
        "max_distance_mm": fidelity["max_mm"], "histogram": q["histogram"],
    }


def _repeats(h: float, quick: bool) -> int:
    return 1 if h < 1.2 else (3 if quick else 5)


def _ours(array, spacing, origin, iso, h, repeats):
    from algorithms.meshing.isosurface_stuffing import isosurface_stuffing

    def run():
        return isosurface_stuffing(array, iso, h=h, spacing=spacing, origin=origin)

    run()  # warm-up (numba cache load)
    results = []
    cpu: list[float] = []
    timing, result = time_call(_with_cpu(lambda: results.append(run()) or results[-1], cpu), repeats=repeats, warmup=0)
    breakdown = {f"{k}_s": float(np.median([r.seconds[k] for r in results]))
                 for k in ("field", "cut", "warp", "stencil", "output")}
    breakdown["cpu_s"] = float(np.median(cpu))
    tracemalloc.start()
    try:
        run()
        peak = tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()
    return timing, result, breakdown, peak


def _with_cpu(function, seconds: list):
    """``function`` that also appends the process's CPU seconds (all threads) of each call to ``seconds``: on a
    shared machine the wall time grows with the other users' load, the CPU time much less."""
    def timed():
        start = time.process_time()
        result = function()
        seconds.append(time.process_time() - start)
        return result
    return timed


def _optional(name: str) -> bool:
    return importlib.util.find_spec(name) is not None


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Run every case; write ``tetmesh.csv``, ``tetmesh_times.png``, ``tetmesh_angles.png`` and ``tetmesh.json``."""
    configure_vtk()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    load_start = os.getloadavg()
    rows: list[dict[str, Any]] = []
    histograms: dict[str, Any] = {}
    datasets = list(_datasets(quick))
    steps = sum(len(d[5]) + 2 for d in datasets)
    done = 0
    for name, array, spacing, origin, iso, hs, exact in datasets:
        surface = _reference_surface(array, spacing, origin, iso)
        ours_by_h = {}
        for h in hs:
            repeats = _repeats(h, quick)
            timing, result, breakdown, peak = _ours(array, spacing, origin, iso, h, repeats)
            quality = _quality(result.mesh, result.boundary, surface, spacing, exact)
            histograms[f"{name}, stuffing, h {h:g} mm"] = quality.pop("histogram")
            ours_by_h[h] = timing.median
            rows.append({"dataset": name, "method": "stuffing", "h_mm": h, "tetrahedra": result.mesh.n_tetrahedra,
                         "points": result.mesh.n_points, "median_s": timing.median, "min_s": timing.minimum,
                         "repeats": repeats, **breakdown, "ratio_to_ours": 1.0, **quality, "peak_mb": peak,
                         "bytes_per_lattice_point": result.stats["bytes_per_lattice_point"]})
            done += 1
            report(progress, done / steps)
        reference_h = min(ours_by_h, key=lambda h: abs(h - 1.0))
        for method, function in (("vtk-delaunay", vtk_delaunay_tetrahedra), ("vtk-clip-tets", vtk_clip_tetrahedra)):
            repeats = 1 if array.size > 2_000_000 else 3
            cpu: list[float] = []
            call = _with_cpu(lambda f=function: f(array, iso, spacing=spacing, origin=origin), cpu)
            timing, result = time_call(call, repeats=repeats, warmup=0)
            quality = _quality(result.mesh, None, surface, spacing, exact)
            histograms[f"{name}, {method}"] = quality.pop("histogram")
            rows.append({"dataset": name, "method": method, "h_mm": "", "tetrahedra": result.mesh.n_tetrahedra,
                         "points": result.mesh.n_points, "median_s": timing.median, "min_s": timing.minimum,
                         "repeats": repeats, "cpu_s": float(np.median(cpu)),
                         "ratio_to_ours": timing.median / ours_by_h[reference_h], **quality,
                         "peak_mb": ""})
            done += 1
            report(progress, done / steps)
    extras = {name: ("installed" if _optional(name) else "absent: pip install voxelscope[bench] to compare")
              for name in ("tetgen", "pytetwild")}
    csv_path = write_csv(out_dir / "tetmesh.csv", rows, COLUMNS)
    times_path = _plot_times(rows, out_dir / "tetmesh_times.png")
    angles_path = _plot_angles(histograms, out_dir / "tetmesh_angles.png")
    info = machine_info()
    json_path = write_json(out_dir / "tetmesh.json", {
        "benchmark": "tetmesh", "quick": quick, "machine": info,
        "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "load_average_1_5_15_min": {"start": list(load_start), "end": list(os.getloadavg())},
        "source_002": SOURCE_002, "optional_references": extras,
        "ratio_to_ours": "VTK's median over ours at the h closest to 1 mm of the same dataset",
        "notes": __doc__, "rows": rows, "histograms": histograms,
        "created": time.strftime("%Y-%m-%d %H:%M:%S"),
    })
    return [csv_path, times_path, angles_path, json_path]


def _plot_times(rows, path: Path) -> Path:
    plt = pyplot()
    figure, axes = plt.subplots(figsize=(7, 5))
    ct = [r for r in rows if r["dataset"].startswith("CT")]
    ours = sorted((r["tetrahedra"], r["median_s"]) for r in ct if r["method"] == "stuffing")
    if ours:
        axes.loglog(*zip(*ours), "o-", label="ours: isosurface stuffing (this machine)")
    axes.loglog([s["tetrahedra"] for s in SOURCE_002], [s["seconds"] for s in SOURCE_002], "s--",
                label="source 002 (2009, its own distance field)")
    for method, marker in (("vtk-delaunay", "^"), ("vtk-clip-tets", "v")):
        points = [(r["tetrahedra"], r["median_s"]) for r in ct if r["method"] == method]
        if points:
            axes.loglog(*zip(*points), marker, markersize=9, label=f"VTK {method[4:]}")
    axes.axhline(3.0, color="grey", lw=0.8, ls=":")
    axes.set_xlabel("tetrahedra")
    axes.set_ylabel("time end to end, median (s)")
    axes.set_title("CT skull at 300 HU")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    return save_figure(figure, path)


def _plot_angles(histograms, path: Path) -> Path:
    plt = pyplot()
    chosen = [k for k in histograms if k.startswith("CT") and ("h 1 mm" in k or "vtk" in k or "h 1.5 mm" in k)]
    chosen = chosen or list(histograms)[:3]
    figure, axes = plt.subplots(len(chosen), 1, figsize=(7, 1.8 * len(chosen) + 0.5), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, key in zip(axes, chosen):
        edges = np.asarray(histograms[key]["edges"])
        counts = np.asarray(histograms[key]["counts"], dtype=np.float64)
        ax.bar(edges[:-1], counts / max(counts.sum(), 1), width=np.diff(edges), align="edge")
        ax.set_title(key, fontsize=9)
        ax.set_ylabel("share")
        ax.axvspan(0, 10.7, color="red", alpha=0.08)
        ax.axvspan(164.8, 180, color="red", alpha=0.08)
    axes[-1].set_xlabel("dihedral angle (degrees)")
    axes[-1].set_xlim(0, 180)
    return save_figure(figure, path)
