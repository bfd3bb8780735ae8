"""Benchmark: peak memory (resident set size) of meshing and rendering a large volume, one command per process.

Volume
------
The CT head phantom (:func:`app.datasets.ct_head_phantom`) on a 512^3 grid of int16 samples, 0.47 mm voxels
(256 MiB of samples; quick: 256^3, 32 MiB), written once as an uncompressed NIfTI file in the output folder and
reused by later runs.

Commands
--------
Each is ``python -m app.cli ...`` in a fresh process, exactly as a user runs it; its peak RSS is the kernel's
high-water mark of that process (``VmHWM`` of ``/proc/self/status``, read as it exits), so everything counts: the
interpreter and libraries, reading the file, the work, writing the output. (``ru_maxrss`` of the child is not used:
Linux carries the RSS of the forked benchmark process over into it.)

- ``baseline``: the interpreter with NumPy, VTK, numba and Voxelscope's command line imported, no volume: the
  floor under every command.
- ``info``: reading the volume (and computing its value range): the floor of every command that reads it.
- ``mesh --method marching-cubes`` and ``mesh --method flying-edges`` at 300 HU, binary STL with its sidecar (the
  validity report included).
- ``render --mode shear-warp --parallel`` and ``render --mode raymarch``, 512 x 512 pixels, the ct-bone preset.

Warm-up
-------
Our kernels are numba functions compiled on first use and cached on disk (``cache=True``). Before measuring, every
command runs once on the phantom at 48^3 (same dtype, so the same compiled signatures), so the measured runs load
the kernels from the cache as every run after the first does; a first run after installing (or after a kernel
changed) compiles them and peaks higher (``render raymarch`` on 512^3 with an empty cache: 595 MiB, 2.33x, measured
once by hand with ``NUMBA_CACHE_DIR`` set to an empty folder). The JSON lists the warm-up runs' exit codes.

Measured
--------
``peak_mib``, ``ratio`` = peak RSS / bytes of the volume's samples (the issue's measure: meshing and shear-warp at
most 3, ray marching at most 2), ``above_reading_mib`` = peak minus the ``info`` run's, ``seconds`` (wall time of the
whole command) and what the command reported (triangles for meshes, frame numbers for renders). One run per
command: the peak of a deterministic command varies by a few MiB between runs.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from algorithms.common.progress import ProgressCallback, report

from ..datasets import ct_head_phantom
from ..io import save_volume
from .common import machine_info, pyplot, save_figure, write_csv, write_json

SIZE = 512
QUICK_SIZE = 256
WARM_UP_SIZE = 48
COLUMNS = ("command", "target_ratio", "peak_mib", "ratio", "above_reading_mib", "seconds", "exit_code", "volume_mib",
           "shape", "triangles", "details")
#: Ratio of peak RSS to the volume's bytes each command must stay within (issue 20).
TARGETS = {"mesh marching-cubes": 3.0, "mesh flying-edges": 3.0, "render shear-warp": 3.0, "render raymarch": 2.0}

_BASELINE = "import numpy, numba, vtkmodules.vtkRenderingOpenGL2, app.cli.mesh, app.cli.render, app.modes; " \
            "app.modes.mode_names()"


def volume_file(out_dir: Path, size: int, progress: ProgressCallback = None) -> Path:
    """The phantom on a ``size``^3 int16 grid as NIfTI in ``out_dir`` (made once, 0.47 mm voxels at 512^3)."""
    path = Path(out_dir) / f"ct_phantom_{size}.nii"
    if path.exists():
        return path

    spacing = 240.0 / size
    volume = ct_head_phantom((size, size, size), (spacing, spacing, spacing))
    report(progress, 0.5)
    return save_volume(volume, path)


#: Runs a module (``-m NAME ARGS``) or code (``-c CODE``) and writes the process's VmHWM (KiB) to a file at exit.
_RUNNER = """
import atexit, runpy, sys
target = sys.argv[1]
def write_peak():
    with open('/proc/self/status') as status:
        peak = next(line.split()[1] for line in status if line.startswith('VmHWM:'))
    with open(target, 'w') as handle:
        handle.write(peak)
atexit.register(write_peak)
if sys.argv[2] == '-m':
    sys.argv = sys.argv[3:]
    runpy.run_module(sys.argv[0], run_name='__main__', alter_sys=True)
else:
    exec(sys.argv[3])
"""


def peak_rss(arguments: list[str], log: Path) -> dict[str, Any]:
    """Run ``python arguments...`` (``-m module ...`` or ``-c code``) in a new process; its peak RSS (MiB), wall
    seconds, exit code, standard output and error."""
    peak_file = log.with_suffix(".peak")
    peak_file.unlink(missing_ok=True)
    start = time.perf_counter()
    with open(log, "w") as stdout, open(log.with_suffix(".err"), "w") as stderr:
        process = subprocess.run([sys.executable, "-c", _RUNNER, str(peak_file), *arguments], stdout=stdout,
                                 stderr=stderr, cwd=Path(__file__).resolve().parents[2])
    seconds = time.perf_counter() - start
    peak = int(peak_file.read_text()) / 1024.0 if peak_file.exists() else float("nan")
    return {"peak_mib": peak, "seconds": seconds, "exit_code": process.returncode, "stdout": log.read_text(),
            "stderr": log.with_suffix(".err").read_text()}


def _commands(path: Path, work: Path) -> list[tuple[str, list[str]]]:
    cli = ["-m", "app.cli"]
    return [
        ("baseline", ["-c", _BASELINE]),
        ("info", [*cli, "info", str(path), "--json"]),
        ("mesh marching-cubes", [*cli, "mesh", str(path), "--method", "marching-cubes", "--iso", "300", "-o",
                                 str(work / "mc.stl"), "--force", "--json"]),
        ("mesh flying-edges", [*cli, "mesh", str(path), "--method", "flying-edges", "--iso", "300", "-o",
                               str(work / "fe.stl"), "--force", "--json"]),
        ("render shear-warp", [*cli, "render", str(path), "--mode", "shear-warp", "--parallel", "-o",
                               str(work / "shear_warp.png"), "--force", "--json"]),
        ("render raymarch", [*cli, "render", str(path), "--mode", "raymarch", "-o", str(work / "raymarch.png"),
                             "--force", "--json"]),
    ]


def warm_up_kernels(out_dir: Path, progress: ProgressCallback = None) -> dict[str, int]:
    """Run every command once on the phantom at ``WARM_UP_SIZE``^3 so numba's disk cache holds the compiled kernels;
    the exit code of each (a failed warm-up only means the measured run may compile)."""
    folder = Path(out_dir) / "memory_warm_up"
    folder.mkdir(parents=True, exist_ok=True)
    path = volume_file(folder, WARM_UP_SIZE)
    commands = [(name, arguments) for name, arguments in _commands(path, folder) if name != "baseline"]
    codes = {}
    for index, (name, arguments) in enumerate(commands):
        codes[name] = peak_rss(arguments, folder / f"{name.replace(' ', '_')}.log")["exit_code"]
        report(progress, (index + 1) / len(commands))
    return codes


def _details(name: str, stdout: str) -> tuple[Any, str]:
    """Triangles of a mesh and a short note of what the command reported."""
    try:
        data = json.loads(stdout)
    except json.JSONDecodeError:
        return "", ""
    if name.startswith("mesh"):
        return data["written"]["triangles"], f"{data['written']['triangles']} triangles, watertight=" \
                                             f"{data['validity']['watertight']}"
    if name.startswith("render"):
        return "", f"set-up {data.get('setup_seconds', 0.0):.1f} s"
    return "", ""


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    """Measure every command once on the phantom; write CSV, a bar chart and JSON to ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    work = out_dir / "memory_outputs"
    work.mkdir(exist_ok=True)
    size = QUICK_SIZE if quick else SIZE
    path = volume_file(out_dir, size, lambda f: report(progress, 0.15 * f))
    warm_up = warm_up_kernels(out_dir, lambda f: report(progress, 0.15 + 0.05 * f))
    volume_mib = size**3 * 2 / 2**20
    commands = _commands(path, work)
    rows: list[dict[str, Any]] = []
    reading = None
    for index, (name, arguments) in enumerate(commands):
        result = peak_rss(arguments, work / f"{name.replace(' ', '_')}.log")
        if result["exit_code"] != 0:
            raise RuntimeError(f"{name} failed: {result['stderr'].strip()[-500:]}")
        if name == "info":
            reading = result["peak_mib"]
        triangles, details = _details(name, result["stdout"])
        rows.append({"command": name, "target_ratio": TARGETS.get(name, ""), "peak_mib": result["peak_mib"],
                     "ratio": result["peak_mib"] / volume_mib,
                     "above_reading_mib": result["peak_mib"] - reading if reading is not None else "",
                     "seconds": result["seconds"], "exit_code": result["exit_code"], "volume_mib": volume_mib,
                     "shape": f"{size}x{size}x{size}", "triangles": triangles, "details": details})
        report(progress, 0.2 + 0.8 * (index + 1) / len(commands))
    csv_path = write_csv(out_dir / "memory.csv", rows, COLUMNS)
    plot_path = _plot(rows, out_dir / "memory.png", size)
    json_path = write_json(out_dir / "memory.json", {
        "benchmark": "memory",
        "quick": quick,
        "machine": machine_info(),
        "volume": {"file": str(path), "shape": [size] * 3, "dtype": "int16", "mib": volume_mib},
        "targets": TARGETS,
        "warm_up": warm_up,
        "within_targets": {row["command"]: row["ratio"] <= TARGETS[row["command"]] for row in rows
                           if row["command"] in TARGETS},
        "notes": __doc__,
        "rows": rows,
    })
    return [csv_path, plot_path, json_path]


def _plot(rows: list[dict[str, Any]], path: Path, size: int) -> Path:
    plt = pyplot()
    figure, axes = plt.subplots(figsize=(9, 4.5))
    names = [row["command"] for row in rows]
    ratios = [row["ratio"] for row in rows]
    bars = axes.bar(range(len(rows)), ratios, color=["#999999" if name in ("baseline", "info") else "#4c72b0"
                                                    for name in names])
    for bar, row in zip(bars, rows):
        axes.annotate(f"{row['peak_mib']:.0f} MiB", (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                      ha="center", va="bottom", fontsize=8)
    for target, style in ((3.0, "--"), (2.0, ":")):
        axes.axhline(target, color="#c44e52", linestyle=style, linewidth=1, label=f"{target:g}x the volume")
    axes.set_xticks(range(len(rows)))
    axes.set_xticklabels(names, rotation=20, ha="right", fontsize=8)
    axes.set_ylabel("peak RSS / volume bytes")
    axes.set_title(f"Peak memory per command, CT phantom {size}^3 int16 ({size**3 * 2 / 2**20:.0f} MiB)")
    axes.legend(fontsize=8)
    return save_figure(figure, path)
