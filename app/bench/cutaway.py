"""Cut-away benchmark (issue 15): the selection volume of source 002 (Kähler, *Vergleich von Volumenmodellen*, MSc
thesis, TU Kaiserslautern, about 2009, sections 2.5 and 3.3.1) in every volume mode, in the same run.

- **Frame time with and without a tool**: the CT sample (the FORBILD head, 512 x 512 x 176) at 512 x 512 (``--quick``:
  the head on 256 x 256 x 88 voxels at 256 x 256), ``ct-bone``, each volume mode (``raymarch``, ``slicing``, ``shear-warp`` when it honours tools,
  ``vtk-gpu``, ``vtk-cpu``) in ``ROUNDS`` rounds of ``FRAMES`` frames of a turning camera (medians), the frames without
  a tool, with it and on the pre-masked volume timed in turns so that outside load cannot favour one; with a sphere,
  a box rotated by 45 degrees and a mesh-shaped tool (the Stanford bunny, voxelised at 64 voxels, when
  ``../shared/data/meshes`` is present), unshaded and, for ``raymarch`` (source 002 measured with Blinn-Phong), shaded.
  The ratio with/without is set beside source 002's 3.7x (11 fps -> 3 fps on a 256^3 volume with local lighting).
  For our renderers the frame of the volume pre-masked at the tool's place is timed too: once the front is cut
  away rays travel further (fewer stop early), so ``ratio_to_premasked`` isolates the cost of the per-sample test
  from the cost of showing more of the volume.
- **Agreement**: the start frame of each volume and surface mode with the sphere against the same mode's frame of the volume whose
  voxels inside the sphere were set to the background value beforehand (foreground PSNR, binary evaluation,
  unshaded), and against the uncut frame (how much the cut changes).
- **Time per tool move** on a 256^3 volume (median of ``MOVES`` moves of a sphere): our renderers rebuild the tools'
  compact form only (per-sample evaluation, no data rewrite); ``vtk-gpu`` needs a new mask on its grid, ``vtk-cpu`` a
  masked copy of the volume, the surface modes the CSG difference (then a new extraction, not counted).

Nothing is asserted; the issue's points (set-up per move <= 5 ms at 256^3; frame with a tool <= 1.3x the frame
without for our renderers; PSNR >= 30 dB) are read off ``cutaway_frames.csv``, ``cutaway_moves.csv`` and
``cutaway_agreement.csv``. Run it on a quiet machine for numbers worth quoting.
"""

from __future__ import annotations

import resource
import time
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.progress import ProgressCallback, report
from algorithms.references.vtk_cutaway import mask_image

from ..io.meshes import load_mesh
from ..modes import get_mode
from ..pipeline.headless import RenderSettings, render_item
from ..scene import VolumeItem
from .common import ct_volume, machine_info, pyplot, save_figure, write_csv, write_json

FRAMES = 4  # per round
ROUNDS = 3
QUICK_FRAMES = 3
QUICK_ROUNDS = 1
MOVES = 20
SOURCE_SLOWDOWN = 11.0 / 3.0  # source 002, 2.5.2: 11 fps with Blinn-Phong, 3 fps with the selection volume
VOLUME_MODES = ("raymarch", "slicing", "shear-warp", "vtk-gpu", "vtk-cpu")
SURFACE_MODES = ("marching-cubes", "flying-edges", "voxel-faces")  # agreement only (their cut is a re-extraction)
SPHERE = "sphere:0,-40,120,100"  # the vertex of the head, as in tests/app/test_cutaways.py
BOX = "box:10,-50,30,80,60,50,0,0,45"
MESHES = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "meshes"


def _bunny_tool():
    """The Stanford bunny scaled to 90 mm and placed at the front of the phantom's head, voxelised at 64 voxels;
    None (and a reason) when the shared meshes are absent."""
    from algorithms.compare.triangles import surface_arrays
    from algorithms.fields.cutaway_tools import mesh_tool

    path = MESHES / "stanford-bunny.obj.gz"
    if not path.exists():
        return None, f"{path} is absent: no mesh-shaped tool"
    mesh = load_mesh(path)
    points, triangles = surface_arrays(mesh.polydata)
    low, high = points.min(axis=0), points.max(axis=0)
    points = (points - (low + high) / 2) * (90.0 / float(np.max(high - low))) + np.array([0.0, -60.0, 30.0])
    return mesh_tool(points, triangles, voxels=64), "stanford-bunny.obj.gz, 90 mm, voxelised at 64 voxels"


def _tools():
    from ..cutaways import parse_cut

    tools = {"sphere": parse_cut(SPHERE), "box 45 degrees": parse_cut(BOX)}
    bunny, note = _bunny_tool()
    if bunny is not None:
        tools["mesh (bunny)"] = bunny
    return tools, note


def _accepting(name: str) -> bool:
    return get_mode(name).capabilities.accepts_cutaways


def _frame_seconds(item, mode, shading, size, frames, tool=None) -> float:
    """Median frame time (s) of ``mode`` on ``item`` over ``frames`` frames of the turning camera."""
    settings = RenderSettings(mode=get_mode(mode), size=size, shading=shading, frames=frames, parallel=mode == "shear-warp",
                              tools=() if tool is None else (tool,))
    return float(render_item(item, settings).info["frame_seconds"])


def _frames(rows, item, modes, tools, size, frames, rounds, progress) -> None:
    """Frame times with and without each tool, the three (uncut, cut, pre-masked) timed in turns ``rounds`` times
    (each a run of ``frames`` frames of the same turning camera), so that load from outside the benchmark falls on
    all of them alike; the ratios are medians over the rounds of each round's ratio."""
    from ..cutaways import masked_volume

    variants = [(mode, False) for mode in modes] + [("raymarch", True)]
    steps = max(len(variants) * len(tools), 1)
    done = 0
    for mode, shading in variants:
        ours = mode in ("raymarch", "slicing", "shear-warp")
        uncut_all: list[float] = []
        tool_rows = []
        for label, tool in tools.items():
            # The same mode on the volume pre-masked at the tool's place: the same samples survive the cut (rays
            # reach further once the front is cut away), so that ratio is the cost of the per-sample test alone.
            masked_item = VolumeItem("pre-masked", volume=masked_volume(item.volume, [tool])) if ours else None
            uncut, cut, premasked = [], [], []
            for _ in range(rounds):
                uncut.append(_frame_seconds(item, mode, shading, size, frames))
                cut.append(_frame_seconds(item, mode, shading, size, frames, tool))
                if masked_item is not None:
                    premasked.append(_frame_seconds(masked_item, mode, shading, size, frames))
            uncut_all += uncut
            ratios = [c / u for c, u in zip(cut, uncut)]
            to_premasked = [c / p for c, p in zip(cut, premasked)]
            tool_rows.append({"mode": mode, "shading": shading, "tool": label, "median_frame_s": median(cut),
                              "uncut_frame_s": median(uncut), "ratio_to_uncut": median(ratios),
                              "ratio_to_uncut_range": f"{min(ratios):.3f}-{max(ratios):.3f}",
                              "premasked_frame_s": median(premasked) if premasked else None,
                              "ratio_to_premasked": median(to_premasked) if to_premasked else None,
                              "source_002_ratio": SOURCE_SLOWDOWN, "ours": ours, "frames": frames,
                              "rounds": rounds, "size": f"{size[0]}x{size[1]}"})
            done += 1
            report(progress, 0.6 * done / steps)
        rows.append({"mode": mode, "shading": shading, "tool": "none", "median_frame_s": median(uncut_all),
                     "uncut_frame_s": median(uncut_all), "ratio_to_uncut": 1.0, "ratio_to_uncut_range": "",
                     "premasked_frame_s": None, "ratio_to_premasked": None, "source_002_ratio": SOURCE_SLOWDOWN,
                     "ours": ours, "frames": frames, "rounds": rounds * len(tools), "size": f"{size[0]}x{size[1]}"})
        rows.extend(tool_rows)


def median(values) -> float:
    return float(np.median(values))


def _agreement(item, volume, modes, sphere, size) -> list[dict[str, Any]]:
    from algorithms.compare.image_metrics import psnr_foreground

    from ..cutaways import masked_volume

    pre = VolumeItem("pre-masked", volume=masked_volume(volume, [sphere]))
    rows = []
    for mode in modes:
        settings = dict(mode=get_mode(mode), size=size, shading=False, parallel=mode == "shear-warp")
        cut = render_item(item, RenderSettings(tools=(sphere,), **settings)).image
        masked = render_item(pre, RenderSettings(**settings)).image
        plain = render_item(item, RenderSettings(**settings)).image
        foreground = (cut.max(axis=-1) > 2) | (plain.max(axis=-1) > 2)
        changed = np.abs(cut.astype(np.int16) - plain.astype(np.int16)).max(axis=-1) > 25
        rows.append({"mode": mode, "tool": SPHERE, "psnr_vs_premasked_db": psnr_foreground(cut, masked),
                     "psnr_vs_uncut_db": psnr_foreground(cut, plain),
                     "changed_foreground_share": float(changed[foreground].mean())})
    return rows


def _moves(shape=(256, 256, 256)) -> list[dict[str, Any]]:
    """Median seconds per move of a sphere tool on a 256^3 volume, per kind of consumer."""
    from algorithms.common.cutaway import removal_field
    from algorithms.fields.cutaway_tools import cut_volume, sphere_tool, tool_set

    rng = np.random.default_rng(0)
    array = rng.integers(-1000, 1500, size=shape, dtype=np.int16)
    spacing = (1.0, 1.0, 1.0)
    centres = [(100 + 3 * m, 120 + 2 * m, 110 - m) for m in range(MOVES)]
    removal_field(tool_set([sphere_tool((0, 0, 0), 5)]), (4, 4, 4), spacing)  # load the kernels first
    rows = []

    def timed(label, what, work):
        seconds = []
        for centre in centres:
            tools = tool_set([sphere_tool(centre, 40.0)])
            start = time.perf_counter()
            work(tools, centre)
            seconds.append(time.perf_counter() - start)
        rows.append({"consumer": label, "what": what, "median_ms": 1000 * float(np.median(seconds)),
                     "max_ms": 1000 * float(np.max(seconds)), "moves": len(seconds),
                     "volume": "x".join(map(str, shape[::-1]))})

    timed("ours (raymarch, slicing, shear-warp)", "the tools' compact form (ToolSet) in the volume frame; "
          "no data rewrite", lambda tools, centre: tool_set([sphere_tool(centre, 40.0)], np.eye(4)).packed())
    timed("vtk-gpu", "binary mask on the mapper's grid (SetMaskInput)",
          lambda tools, centre: mask_image(removal_field(tools, shape, spacing) >= 0, spacing))
    timed("vtk-cpu", "masked copy of the volume (no mask input)",
          lambda tools, centre: np.where(removal_field(tools, shape, spacing) >= 0, array, np.int16(-1000)))
    timed("surfaces", "CSG difference written into a copy (then extraction)",
          lambda tools, centre: cut_volume(array, tools.with_settings(evaluation="distance"), spacing, 300.0))
    return rows


def _plot(rows, path: Path) -> Path:
    plt = pyplot()
    figure, axis = plt.subplots(figsize=(9, 4.5))
    labels = sorted({(r["mode"], r["shading"]) for r in rows}, key=lambda v: (v[1], v[0]))
    tools = list(dict.fromkeys(r["tool"] for r in rows))
    width = 0.8 / len(tools)
    for t, tool in enumerate(tools):
        values = [next((r["median_frame_s"] * 1000 for r in rows if (r["mode"], r["shading"]) == label
                        and r["tool"] == tool), np.nan) for label in labels]
        axis.bar(np.arange(len(labels)) + t * width, values, width, label=tool)
    axis.set_xticks(np.arange(len(labels)) + 0.4 - width / 2)
    axis.set_xticklabels([f"{m}{' shaded' if s else ''}" for m, s in labels], rotation=20)
    axis.set_ylabel("median frame time (ms)")
    axis.set_title("Frame time with and without a cut-away tool (CT phantom)")
    axis.legend()
    return save_figure(figure, path)


def run(out_dir, *, quick: bool = False, progress: ProgressCallback = None) -> list[Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    volume = ct_volume(quick)
    item = VolumeItem("sample", volume=volume)
    size = (256, 256) if quick else (512, 512)
    frames = QUICK_FRAMES if quick else FRAMES
    modes = [m for m in VOLUME_MODES if _accepting(m)]
    skipped = [m for m in VOLUME_MODES if m not in modes]
    tools, mesh_note = _tools()
    if quick:
        tools = {k: v for k, v in tools.items() if k != "box 45 degrees"}
    frame_rows: list[dict[str, Any]] = []
    _frames(frame_rows, item, modes, tools, size, frames, QUICK_ROUNDS if quick else ROUNDS, progress)
    surface_modes = [m for m in SURFACE_MODES if _accepting(m)]
    agreement = _agreement(item, volume, modes + surface_modes, tools["sphere"], (256, 256) if quick else (512, 512))
    report(progress, 0.8)
    moves = _moves((96, 96, 96) if quick else (256, 256, 256))
    report(progress, 0.95)
    paths = [
        write_csv(out_dir / "cutaway_frames.csv", frame_rows),
        write_csv(out_dir / "cutaway_agreement.csv", agreement),
        write_csv(out_dir / "cutaway_moves.csv", moves),
        _plot(frame_rows, out_dir / "cutaway_frames.png"),
    ]
    ours = [r for r in frame_rows if r["ours"] and r["tool"] != "none"]
    paths.append(write_json(out_dir / "cutaway.json", {
        "benchmark": "cutaway", "quick": quick, "machine": machine_info(),
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "modes": modes, "modes_without_tools": skipped, "mesh_tool": mesh_note,
        "source_002_slowdown": SOURCE_SLOWDOWN,
        "largest_ratio_ours": max((r["ratio_to_uncut"] for r in ours), default=None),
        "largest_ratio_to_premasked_ours": max((r["ratio_to_premasked"] for r in ours), default=None),
        "frames": frame_rows, "agreement": agreement, "moves": moves,
    }))
    report(progress, 1.0)
    return paths
