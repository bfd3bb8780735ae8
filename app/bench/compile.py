"""Benchmark: how long the first call of each numba kernel group spends compiling, and how long it takes when the
kernels are already in the on-disk cache.

Our kernels are ``@njit(cache=True)`` functions: numba compiles each on its first call and stores the machine code
(``*.nbi`` index, ``*.nbc`` data) in a cache folder, from which later processes load it. This benchmark measures,
per *group* of kernels that one application feature uses (:data:`GROUPS`):

- **cold first call**: a fresh process whose cache folder is a new, empty temporary folder; the first call of the
  group's workload (compile + run);
- **warm second call**: the same call again in that process (run only);
- **compile** = cold first - warm second (what compiling, and a first call's one-off costs such as starting numba's
  thread pool, add);
- **cached first call**: a second fresh process on the folder the cold run filled (cache load + run).

Import time is excluded: each workload imports its modules and builds its inputs before the timed calls
(``setup_s``). numba's event API records every ``numba:compile`` event (one per dispatcher and signature compiled;
cache loads fire none); events nest when a kernel compiles its callees, so each dispatcher (``module.qualname``) gets
an *inclusive* and a *self* time (less the nested compiles). Saving to the cache follows the event (wall time only).
After the calls, every dispatcher of the project (``algorithms.*`` modules) lists its signatures.

Cache folder: both ``VOXELSCOPE_NUMBA_CACHE`` (the per-user kernel cache of
``algorithms/common/kernel_cache.py``) and ``NUMBA_CACHE_DIR`` (numba's own, used by checkouts without that module
and by kernels outside ``algorithms/``) point at the temporary folder; ``NUMBA_CACHE_LOCATOR_CLASSES`` is removed
from the child's environment (this process's ``algorithms`` sets it to a locator an older checkout lacks).

Checkouts: ``against=PATH`` (``--against PATH``) measures a second checkout in the same run, e.g. a ``git worktree``
of an older commit: each process runs in the checkout measured (working folder and ``PYTHONPATH``) and gets the
workloads as source text (``python -c``), so that checkout needs nothing of this module; the workloads use
long-standing public APIs only.

Turns: ``REPEATS`` repeats (``--quick``: 1), each rotating the order of the groups and alternating which checkout
goes first. Medians over the repeats. Also per repeat: all groups in **one** fresh process (cold, then cached):
shared helpers compile once there, so its total is below the sum of the groups.

Writes ``compile.csv`` (per group and checkout: medians and samples; also the sum over groups and the one-process
run), ``kernels.csv`` (per checkout, group and dispatcher: median inclusive and self seconds of the cold runs, the
signatures), ``compile.json`` (machine, numba, command line, checkouts and commits, samples) and ``compile.png``;
prints a short table. Nothing is asserted.
"""

from __future__ import annotations

import inspect
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from algorithms.common.progress import ProgressCallback, report

REPEATS = 3
QUICK_REPEATS = 1
#: Seconds one process may take (a cold process of every group compiles everything).
PROCESS_TIMEOUT = 3600
#: Prefix of the one line of JSON a worker process prints.
MARKER = "@@voxelscope-compile@@"
ALL = "all (one process)"
TOTAL = "sum of groups"
ROOT = Path(__file__).resolve().parents[2]


# -- Inputs and workloads: shipped to the worker process as source text (they import what they use themselves) ---
def _ct_volume(size=48, read_only=False):
    """A CT-like int16 volume (HU): a sphere of 700 in air of -1000, spacing 1 mm; and its spacing. ``read_only``:
    as the renderers' VTK filters pass it (a read-only view of VTK's memory)."""
    import numpy as np

    k, j, i = np.mgrid[:size, :size, :size]
    centre = (size - 1) / 2.0
    inside = (i - centre) ** 2 + (j - centre) ** 2 + (k - centre) ** 2 <= (size / 3.0) ** 2
    volume = np.where(inside, 700, -1000).astype(np.int16)
    volume.setflags(write=not read_only)
    return volume, (1.0, 1.0, 1.0)


def _table():
    """A bone-like transfer table over the volume's value range, 4096 entries like the application's."""
    from algorithms.common.transfer import TransferTable

    return TransferTable.from_points([[-1000, 0, 0, 0], [300, 0.9, 0.8, 0.7], [700, 1, 1, 1]],
                                     [[-1000, 0], [150, 0], [700, 0.8]], (-1000.0, 700.0))


def _camera(parallel=False, size=48):
    """A camera looking at the volume's centre from the front (LPS: from -y), parallel or perspective."""
    from algorithms.common.camera import Camera

    centre = (size - 1) / 2.0
    return Camera((centre, centre - 4.0 * size, centre), (centre, centre, centre), (0.0, 0.0, 1.0),
                  parallel_projection=parallel, parallel_scale=0.6 * size)


def _sphere_mesh(voxels=48):
    """A closed triangle mesh (vtkSphereSource, radius 20 mm, triangulated) as the application reads a mesh item
    (``polydata_arrays``: float32 points, int64 triangles), and a grid of ``voxels`` cubic voxels around it with 2
    voxels of padding (the application's kind of grid)."""
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    from algorithms.common.grid import Grid
    from algorithms.common.vtk_bridge import polydata_arrays

    source = vtkSphereSource()
    source.SetRadius(20.0)
    source.SetThetaResolution(24)
    source.SetPhiResolution(24)
    triangulate = vtkTriangleFilter()
    triangulate.SetInputConnection(source.GetOutputPort())
    triangulate.Update()
    points, triangles = polydata_arrays(triangulate.GetOutput())
    bounds = [float(v) for pair in zip(points.min(axis=0), points.max(axis=0)) for v in pair]
    return points, triangles, Grid.around(bounds, voxels=voxels, padding=2)


def _analytic_fields(size=48):
    """Two float32 signed distance fields (mm, negative inside) on the same grid: a sphere and a box."""
    import numpy as np

    k, j, i = np.mgrid[:size, :size, :size].astype(np.float32)
    c = (size - 1) / 2.0
    sphere = np.sqrt((i - c) ** 2 + (j - c) ** 2 + (k - c) ** 2) - size / 3.0
    q = np.stack([np.abs(i - c - 8), np.abs(j - c - 8), np.abs(k - c - 8)]) - size / 5.0
    box = np.linalg.norm(np.maximum(q, 0), axis=0) + np.minimum(q.max(axis=0), 0)
    return sphere.astype(np.float32), box.astype(np.float32)


def workload_marching_cubes():
    """Marching cubes of the int16 CT volume at 300 HU with normals (the ``marching-cubes`` mesh mode's call)."""
    import numpy as np

    from algorithms.surfaces.marching_cubes import marching_cubes

    volume, spacing = _ct_volume()
    return lambda: marching_cubes(volume, [300.0], spacing=np.array(spacing), origin=np.zeros(3), normals=True)


def workload_marching_cubes_float32():
    """Marching cubes of a float32 field at 0 without normals (how a distance field or CSG result is meshed)."""
    from algorithms.surfaces.marching_cubes import marching_cubes

    field = -_analytic_fields()[0]
    return lambda: marching_cubes(field, 0.0, spacing=(1.0, 1.0, 1.0))


def workload_raymarch():
    """The ray marcher on the read-only int16 volume with jitter, one renderer and 48x48 frame for each lighting
    model (emission, Blinn-Phong, single scattering: one kernel, the model is an argument)."""
    from algorithms.rendering.raymarch import RaymarchRenderer

    (volume, spacing), table, camera = _ct_volume(read_only=True), _table(), _camera()

    def call():
        for lighting in ("emission", "phong", "scatter"):
            RaymarchRenderer(volume, spacing, table, lighting=lighting, jitter=True).render(camera, 48, 48)
    return call


def workload_shear_warp():
    """Shear-warp, shaded, lazily encoded (as its filter builds it): one parallel and one perspective 48x48 frame."""
    from algorithms.rendering.shear_warp import ShearWarpRenderer

    (volume, spacing), table = _ct_volume(read_only=True), _table()

    def call():
        renderer = ShearWarpRenderer(volume, spacing, table, shading=True, lazy=True)
        renderer.render(_camera(parallel=True), 48, 48)
        renderer.render(_camera(parallel=False), 48, 48)
    return call


def workload_texture_slicing():
    """Texture slicing, view-aligned, float compositing (the reference renderer), shaded and jittered, 48x48."""
    from algorithms.rendering.texture_slicing import SlicingRenderer

    (volume, spacing), table, camera = _ct_volume(read_only=True), _table(), _camera()
    return lambda: SlicingRenderer(volume, spacing, table, mode="view", precision="float", shading=True,
                                   jitter=True).render(camera, 48, 48)


def workload_voxel_surfaces():
    """Visible voxel faces, tower strips and their hybrid (L = 10) of the int16 volume at 300 HU."""
    from algorithms.surfaces.tower import hybrid, tower_strips
    from algorithms.surfaces.voxel_faces import voxel_faces

    volume, spacing = _ct_volume()

    def call():
        voxel_faces(volume, threshold=300.0, spacing=spacing)
        hybrid(tower_strips(volume, threshold=300.0, spacing=spacing), max_strip_vertices=10)
    return call


def workload_cutaway():
    """A sphere cut-away tool (binary evaluation, cut normals, as a view passes it): the Blinn-Phong ray marcher and
    parallel shear-warp with the tool, and the cut volume the surface modes mesh."""
    import numpy as np

    from algorithms.fields.cutaway_tools import cut_volume, sphere_tool, tool_set
    from algorithms.rendering.raymarch import RaymarchRenderer
    from algorithms.rendering.shear_warp import ShearWarpRenderer

    volume, spacing = _ct_volume()
    rendered, table = _ct_volume(read_only=True)[0], _table()
    tools = tool_set([sphere_tool((23.5, 10.0, 23.5), 12.0)], np.eye(4), evaluation="binary", width=1.0)

    def call():
        RaymarchRenderer(rendered, spacing, table, lighting="phong", jitter=True).render(_camera(), 48, 48,
                                                                                         tools=tools)
        ShearWarpRenderer(rendered, spacing, table, shading=True, lazy=True).render(_camera(parallel=True), 48, 48,
                                                                                   tools=tools)
        cut_volume(volume, tools, spacing, 300.0)
    return call


def workload_voxelise():
    """Voxelising the closed sphere mesh on a 48-voxel grid by the default inside rule (parity)."""
    from algorithms.fields.voxelise import voxelise

    points, triangles, grid = _sphere_mesh()
    return lambda: voxelise(points, triangles, grid)


def workload_winding():
    """Voxelising the sphere mesh by generalised winding numbers (``inside="winding"``)."""
    from algorithms.fields.voxelise import voxelise

    points, triangles, grid = _sphere_mesh()
    return lambda: voxelise(points, triangles, grid, inside="winding")


def workload_distance():
    """The signed distance field of the sphere mesh: exact band of 3 voxels, propagated outside it (its sign by
    parity voxelisation, whose kernels this group compiles too)."""
    from algorithms.fields.distance import signed_distance

    points, triangles, grid = _sphere_mesh()
    return lambda: signed_distance(points, triangles, grid, band_mm=3 * grid.spacing[0], outside="propagate")


def workload_csg():
    """CSG of two float32 distance fields: a sharp difference, a blended union, and the negated, padded field that
    is meshed afterwards."""
    from algorithms.fields.csg import combine, negated_padded

    sphere, box = _analytic_fields()

    def call():
        combine([sphere, box], "difference")
        negated_padded(combine([sphere, box], "union", blend_mm=2.0))
    return call


def workload_isosurface_stuffing():
    """Isosurface stuffing of the int16 volume at 300 HU, lattice spacing 4 mm, alpha 10.7."""
    from algorithms.meshing.isosurface_stuffing import isosurface_stuffing

    volume, spacing = _ct_volume()
    return lambda: isosurface_stuffing(volume, 300.0, h=4.0, spacing=spacing, origin=(0.0, 0.0, 0.0))


#: Group name (``workload_marching_cubes`` -> ``marching-cubes``) -> workload. A workload imports and builds its
#: inputs (untimed) and returns the call to time.
GROUPS: dict[str, Callable[[], Callable[[], Any]]] = {
    function.__name__.removeprefix("workload_").replace("_", "-"): function for function in (
        workload_marching_cubes, workload_marching_cubes_float32, workload_raymarch, workload_shear_warp,
        workload_texture_slicing, workload_voxel_surfaces, workload_cutaway, workload_voxelise, workload_winding,
        workload_distance, workload_csg, workload_isosurface_stuffing)}
_HELPERS = (_ct_volume, _table, _camera, _sphere_mesh, _analytic_fields)


# -- The worker: runs in the child process ----------------------------------------------------------------------
def worker_main(names: Sequence[str], workloads: dict, marker: str = MARKER) -> dict:
    """Run the named groups in this process, in order; print (after ``marker``) and return what was measured.

    Per group: ``setup_s`` (imports and inputs), ``first_s`` and ``second_s`` (the two timed calls), the compile
    events of each phase by dispatcher (``inclusive_s``, ``self_s``, ``events``, ``signatures`` compiled), and
    ``signatures``: every project dispatcher's signatures after the group (cumulative over the process), with its
    cache hits. A group that fails records ``error`` and the next one runs.
    """
    import time as clock
    import traceback

    started = clock.perf_counter()
    import numba
    from numba.core import event
    from numba.core.registry import CPUDispatcher

    def signature_text(types) -> str:
        return "(" + ", ".join(str(t) for t in types) + ")"

    def dispatcher_name(dispatcher) -> str:
        function = dispatcher.py_func
        return f"{function.__module__}.{function.__qualname__}"

    class Recorder(event.Listener):
        """Inclusive and self time of nested ``numba:compile`` events, per dispatcher, into ``self.phase``."""

        def __init__(self):
            self.stack = []
            self.phase = {}

        def on_start(self, ev):
            self.stack.append([clock.perf_counter(), 0.0])

        def on_end(self, ev):
            begin, nested = self.stack.pop()
            inclusive = clock.perf_counter() - begin
            if self.stack:
                self.stack[-1][1] += inclusive
            data = ev.data or {}
            name = dispatcher_name(data["dispatcher"]) if "dispatcher" in data else "?"
            entry = self.phase.setdefault(name, {"inclusive_s": 0.0, "self_s": 0.0, "events": 0, "signatures": []})
            entry["inclusive_s"] += inclusive
            entry["self_s"] += inclusive - nested
            entry["events"] += 1
            entry["signatures"].append(signature_text(data.get("args", ())))

    def project_signatures() -> dict:
        found = {}
        modules = [module for name, module in list(sys.modules.items()) if name.startswith("algorithms.") and module]
        for value in (value for module in modules for value in list(vars(module).values())):
            if isinstance(value, CPUDispatcher) and value.py_func.__module__.startswith("algorithms."):
                if value.signatures and dispatcher_name(value) not in found:
                    found[dispatcher_name(value)] = {"signatures": [signature_text(s) for s in value.signatures],
                                                     "cache_hits": int(sum(value.stats.cache_hits.values()))}
        return found

    recorder = Recorder()
    event.register("numba:compile", recorder)
    out = {"numba": numba.__version__, "import_numba_s": clock.perf_counter() - started, "groups": []}
    for name in names:
        row = {"group": name, "compiles": {}}
        try:
            for phase in ("setup", "first", "second"):
                recorder.phase = row["compiles"][phase] = {}
                begin = clock.perf_counter()
                if phase == "setup":
                    call = workloads[name]()
                else:
                    call()
                row[f"{phase}_s"] = clock.perf_counter() - begin
        except Exception as error:  # a group an older checkout cannot run: recorded, the others go on
            row["error"] = "".join(traceback.format_exception_only(type(error), error)).strip()
        row["signatures"] = project_signatures()
        out["groups"].append(row)
    event.unregister("numba:compile", recorder)
    import algorithms

    out["algorithms_file"] = str(algorithms.__file__)
    print(marker + json.dumps(out), flush=True)
    return out


def worker_program() -> str:
    """The worker's source for ``python -c PROGRAM GROUP...``: the helpers, the workloads and :func:`worker_main`."""
    parts = ["from __future__ import annotations\n\nimport json, sys", f"MARKER = {MARKER!r}"]
    parts += [inspect.getsource(function) for function in (*_HELPERS, *GROUPS.values(), worker_main)]
    parts.append("WORKLOADS = {" + ", ".join(f"{name!r}: {function.__name__}" for name, function in GROUPS.items())
                 + "}")
    parts.append("worker_main(sys.argv[1:], WORKLOADS)")
    return "\n\n".join(parts) + "\n"


# -- Processes (parent side) ------------------------------------------------------------------------------------
def child_environment(checkout: Path, cache_dir: Path) -> dict[str, str]:
    """This process's environment for a worker of ``checkout`` using the cache folder ``cache_dir``."""
    env = {key: value for key, value in os.environ.items() if key != "NUMBA_CACHE_LOCATOR_CLASSES"}
    env.update(VOXELSCOPE_NUMBA_CACHE=str(cache_dir), NUMBA_CACHE_DIR=str(cache_dir), PYTHONPATH=str(checkout))
    return env


def run_worker(checkout, names: Sequence[str], cache_dir, *, timeout: float = PROCESS_TIMEOUT) -> dict:
    """Run the groups ``names`` in one fresh process of ``checkout`` with ``cache_dir`` as its kernel cache; the
    worker's result (see :func:`worker_main`) plus ``wall_s``, the whole process's seconds. RuntimeError when the
    process fails or imported ``algorithms`` from elsewhere."""
    checkout = Path(checkout).resolve()
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    process = subprocess.run([sys.executable, "-c", worker_program(), *names], cwd=checkout,
                             env=child_environment(checkout, Path(cache_dir)), capture_output=True, text=True,
                             timeout=timeout)
    wall_s = time.perf_counter() - start
    lines = [line for line in process.stdout.splitlines() if line.startswith(MARKER)]
    if process.returncode != 0 or not lines:
        raise RuntimeError(f"the compile worker ({', '.join(names)}) in {checkout} failed with exit code "
                           f"{process.returncode}: {process.stderr.strip()[-2000:]}")
    result = json.loads(lines[-1][len(MARKER):])
    if not Path(result["algorithms_file"]).resolve().is_relative_to(checkout):
        raise RuntimeError(f"the worker for {checkout} imported {result['algorithms_file']}")
    return {**result, "wall_s": wall_s}


def cold_and_cached(checkout, names: Sequence[str], cache_dir=None) -> dict[str, Any]:
    """One cold process and then one cached process of ``checkout`` running ``names``: ``{"cold", "cached",
    "cache_files"}`` (how many ``nbi``/``nbc`` files the cold one wrote). ``cache_dir`` (kept) or a new temporary
    folder (removed afterwards)."""
    folder = Path(cache_dir) if cache_dir is not None else Path(tempfile.mkdtemp(prefix="voxelscope-compile-"))
    try:
        cold = run_worker(checkout, names, folder)
        files = {kind: sum(1 for _ in folder.rglob(f"*.{kind}")) for kind in ("nbi", "nbc")}
        cached = run_worker(checkout, names, folder)
    finally:
        if cache_dir is None:
            shutil.rmtree(folder, ignore_errors=True)
    return {"cold": cold, "cached": cached, "cache_files": files}


def project_compiles(compiles: dict) -> dict:
    """The compile events of a phase that are the project's kernels (``algorithms.*``)."""
    return {name: entry for name, entry in compiles.items() if name.startswith("algorithms.")}


def git_state(path) -> dict[str, Any]:
    """``commit``: ``git rev-parse HEAD`` of the checkout at ``path``; ``modified``: whether tracked files differ
    from it (both None outside a git checkout)."""
    try:
        head, status = (subprocess.run(["git", "-C", str(path), *arguments], capture_output=True, text=True)
                        for arguments in (["rev-parse", "HEAD"], ["status", "--porcelain", "--untracked-files=no"]))
    except OSError:
        return {"commit": None, "modified": None}
    if head.returncode != 0:
        return {"commit": None, "modified": None}
    return {"commit": head.stdout.strip(), "modified": bool(status.stdout.strip())}


# -- Turns, medians, files --------------------------------------------------------------------------------------
def _median(values) -> float:
    values = [v for v in values if v is not None and v == v]
    return float(statistics.median(values)) if values else float("nan")


def _sample(run: dict[str, Any], groups: Sequence[str]) -> dict[str, Any]:
    """The numbers of one cold + cached pair over ``groups`` (one group, or all of one process): sums of the
    groups' calls, compile events of the cold process by dispatcher, the signatures after it."""
    cold = {row["group"]: row for row in run["cold"]["groups"]}
    cached = {row["group"]: row for row in run["cached"]["groups"]}
    kernels: dict[str, dict[str, Any]] = {}
    for phase in (phase for name in groups for phase in cold[name]["compiles"].values()):
        for kernel, entry in phase.items():
            summed = kernels.setdefault(kernel, {"inclusive_s": 0.0, "self_s": 0.0, "events": 0, "signatures": []})
            for key in summed:
                summed[key] += entry[key]

    def total(rows, key):
        return sum(rows[name].get(key, float("nan")) for name in groups)

    first, second = total(cold, "first_s"), total(cold, "second_s")
    errors = sorted({row["error"] for rows in (cold, cached) for row in rows.values() if row.get("error")})
    return {
        "cold_first_s": first, "warm_second_s": second, "compile_s": first - second,
        "cached_first_s": total(cached, "first_s"), "setup_s": total(cold, "setup_s"),
        "compile_events_s": sum(entry["self_s"] for entry in kernels.values()),
        "cached_project_compiles": sum(entry["events"] for name in groups for phase in cached[name]["compiles"]
                                       .values() for entry in project_compiles(phase).values()),
        "cache_nbi": run["cache_files"]["nbi"], "cache_nbc": run["cache_files"]["nbc"],
        "kernels": kernels, "signatures": cold[groups[-1]]["signatures"], "error": "; ".join(errors),
    }


def _summary(label: str, commit: str | None, group: str, samples: list[dict[str, Any]]) -> dict[str, Any]:
    """One row of compile.csv: medians over the repeats, and the samples themselves."""
    medians = {key: _median(s[key] for s in samples) for key in
               ("cold_first_s", "warm_second_s", "compile_s", "cached_first_s", "compile_events_s", "setup_s")}
    kernels = set().union(*(s["kernels"] for s in samples)) if "kernels" in samples[0] else None  # not for sums
    row = {"checkout": label, "commit": (commit or "")[:12], "group": group, **medians,
           "cold_over_cached": medians["cold_first_s"] / medians["cached_first_s"],
           **{key: "" for key in ("project_kernels_compiled", "all_kernels_compiled", "cache_nbc",
                                  "cached_project_compiles")}, "repeats": len(samples)}
    if kernels is not None:
        row.update(project_kernels_compiled=sum(1 for k in kernels if k.startswith("algorithms.")),
                   all_kernels_compiled=len(kernels), cache_nbc=max(s["cache_nbc"] for s in samples),
                   cached_project_compiles=max(s["cached_project_compiles"] for s in samples))
    for key in ("cold_first_s", "warm_second_s", "cached_first_s"):
        row[key[:-2] + "_samples"] = ";".join(f"{s[key]:.4g}" for s in samples)
    row["error"] = "; ".join(sorted({s["error"] for s in samples if s.get("error")}))
    return row


def _kernel_rows(label: str, group: str, samples: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """kernels.csv rows of one checkout and group: per dispatcher compiled in the cold runs, medians over them."""
    rows = []
    for kernel in sorted(set().union(*(s["kernels"] for s in samples))):
        entries = [s["kernels"].get(kernel, {"inclusive_s": 0.0, "self_s": 0.0, "signatures": []}) for s in samples]
        held = samples[-1]["signatures"].get(kernel, {}).get("signatures")
        signatures = held if held else sorted(set(entries[-1]["signatures"]))
        rows.append({"checkout": label, "group": group, "kernel": kernel, "project": kernel.startswith("algorithms."),
                     "inclusive_s": _median(e["inclusive_s"] for e in entries),
                     "self_s": _median(e["self_s"] for e in entries), "compiles": len(entries[-1]["signatures"]),
                     "signature_count": len(signatures), "signatures": " | ".join(signatures)})
    return sorted(rows, key=lambda row: -row["self_s"])


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None, against: str | None = None,
        groups: Sequence[str] | None = None) -> list[Path]:
    """Measure every group (or ``groups``) cold, warm and cached, in this checkout and, with ``against``, in that
    checkout too; write ``compile.csv``, ``kernels.csv``, ``compile.json`` and ``compile.png`` to ``out_dir``."""
    from .common import machine_info, write_csv, write_json

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(GROUPS if groups is None else groups)
    unknown = [name for name in names if name not in GROUPS]
    if unknown or not names:
        raise ValueError(f"unknown compile groups {unknown}; choose from {', '.join(GROUPS)}")
    checkouts = {"this": ROOT}
    if against is not None:
        other = Path(against).expanduser().resolve()
        if not (other / "algorithms" / "__init__.py").is_file():
            raise ValueError(f"--against {against}: no checkout of the project there (algorithms/__init__.py)")
        checkouts["against"] = other
    states = {label: git_state(path) for label, path in checkouts.items()}
    repeats = QUICK_REPEATS if quick else REPEATS
    samples: dict[tuple[str, str], list[dict[str, Any]]] = {}
    steps, done = repeats * (len(names) + 1) * len(checkouts), 0
    for repeat in range(repeats):
        shift = repeat % len(names)
        order = names[shift:] + names[:shift]
        labels = list(checkouts) if repeat % 2 == 0 else list(checkouts)[::-1]
        for group in [*order, ALL]:
            members = names if group == ALL else [group]
            for label in labels:
                sample = _sample(cold_and_cached(checkouts[label], members), members)
                samples.setdefault((label, group), []).append(sample)
                done += 1
                report(progress, done / steps)
    rows, kernels = [], []
    for label in checkouts:
        by_repeat = [{key: sum(samples[(label, g)][r][key] for g in names) for key in
                      ("cold_first_s", "warm_second_s", "compile_s", "cached_first_s", "compile_events_s",
                       "setup_s")} for r in range(repeats)]
        for group in [*names, ALL]:
            rows.append(_summary(label, states[label]["commit"], group, samples[(label, group)]))
            kernels += _kernel_rows(label, group, samples[(label, group)])
        rows.append(_summary(label, states[label]["commit"], TOTAL, by_repeat))
    csv_path = write_csv(out_dir / "compile.csv", rows)
    kernels_path = write_csv(out_dir / "kernels.csv", kernels)
    plot_path = _plot(rows, out_dir / "compile.png", list(checkouts))
    machine = machine_info()
    json_path = write_json(out_dir / "compile.json", {
        "benchmark": "compile", "quick": quick, "repeats": repeats, "machine": machine,
        "numba": machine.get("numba"), "command_line": [sys.executable, *sys.argv],
        "checkouts": {label: {"path": str(path), **states[label]} for label, path in checkouts.items()},
        "groups": {name: inspect.getdoc(GROUPS[name]) for name in names}, "notes": __doc__, "rows": rows,
        "samples": {f"{label} / {group}": [{k: v for k, v in s.items() if k not in ("kernels", "signatures")}
                                           for s in runs] for (label, group), runs in samples.items()},
    })
    print_table(rows, list(checkouts))
    return [csv_path, kernels_path, plot_path, json_path]


def print_table(rows: list[dict[str, Any]], labels: list[str]) -> None:
    """Per group: cold compile and cached first call (s) of each checkout, and the ratio of the compiles."""
    by_key = {(row["checkout"], row["group"]): row for row in rows}
    groups = list(dict.fromkeys(row["group"] for row in rows))
    header = f"{'group':<24}" + "".join(f"{label + ' compile':>16}{label + ' cached':>16}" for label in labels)
    print("\n" + header + (f"{'this/against':>14}" if len(labels) > 1 else ""))  # below a progress line
    for group in groups:
        cells = [by_key[(label, group)] for label in labels]
        line = f"{group:<24}" + "".join(f"{c['compile_s']:>16.2f}{c['cached_first_s']:>16.3f}" for c in cells)
        if len(cells) > 1:
            line += f"{cells[0]['compile_s'] / cells[1]['compile_s']:>14.2f}"
        print(line + ("  (errors)" if any(c["error"] for c in cells) else ""))


def _plot(rows: list[dict[str, Any]], path: Path, labels: list[str]) -> Path:
    """Bars per group: cold compile and cached first call per checkout (log scale); ratios above the groups."""
    from .common import pyplot, save_figure

    groups = list(dict.fromkeys(row["group"] for row in rows))
    by_key = {(row["checkout"], row["group"]): row for row in rows}
    figure, axes = pyplot().subplots(figsize=(max(9.0, 0.9 * len(groups) * len(labels)), 5))
    width = 0.8 / (2 * len(labels))
    colours = (("#4c72b0", "#a6bddb"), ("#dd8452", "#fdd0a2"))
    for n, label in enumerate(labels):
        for m, (key, kind) in enumerate((("compile_s", "cold compile"), ("cached_first_s", "cached first call"))):
            offset = (2 * n + m) * width - 0.4 + width / 2
            values = [by_key[(label, g)][key] for g in groups]
            axes.bar([i + offset for i in range(len(groups))], values, width, color=colours[n % 2][m],
                     label=f"{label}: {kind}")
    for i, group in enumerate(groups):
        cells = [by_key[(label, group)] for label in labels]
        ratio = cells[0]["compile_s"] / (cells[1]["compile_s"] if len(cells) > 1 else cells[0]["cached_first_s"])
        axes.annotate(f"x{ratio:.2f}" if len(cells) > 1 else f"x{ratio:.0f}",
                      (i, max(max(c["compile_s"], c["cached_first_s"]) for c in cells)), ha="center", va="bottom",
                      fontsize=8, xytext=(0, 3), textcoords="offset points")
    axes.set_yscale("log")
    axes.set_xticks(range(len(groups)))
    axes.set_xticklabels(groups, rotation=30, ha="right", fontsize=8)
    axes.set_ylabel("seconds (median)")
    ratio = "compile this / against" if len(labels) > 1 else "cold compile / cached first call"
    axes.set_title(f"numba kernels: cold compile vs cached first call; above: {ratio}", fontsize=10)
    axes.legend(fontsize=8)
    return save_figure(figure, path)
