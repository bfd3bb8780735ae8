"""``voxelscope render``: one off-screen picture of any mode (the same view pipeline as the window), optionally
timing frames while the camera turns."""

from __future__ import annotations

import argparse

from .common import (add_cut_arguments, add_input_arguments, add_mode_option_flags, load_item, mode_options_from_args,
                     print_json, refuse_existing, tools_from_args)

NAME = "render"
HELP = "render a volume or mesh off-screen to PNG in any mode, optionally timing frames"
ORDER = 30


def add_arguments(parser) -> None:
    from ..modes import mode_names, modes
    from ..pipeline.cameras import STANDARD_VIEWS
    from ..transfer import preset_names

    add_input_arguments(parser, meshes=True)
    parser.add_argument("--mode", required=True, choices=mode_names(), metavar="MODE",
                        help="render mode (see 'voxelscope modes')")
    parser.add_argument("-o", "--output", required=True, help="output PNG file")
    parser.add_argument("--preset", choices=preset_names(), help="transfer function (default: ct-bone for CT, "
                                                                  "mr-default otherwise)")
    parser.add_argument("--size", nargs=2, type=int, default=(512, 512), metavar=("W", "H"), help="pixels (512 512)")
    parser.add_argument("--view", default="anterior", choices=list(STANDARD_VIEWS),
                        help="side the camera looks from before turning (default anterior)")
    parser.add_argument("--azimuth", type=float, default=0.0, metavar="DEGREES", help="turn the camera about view up")
    parser.add_argument("--elevation", type=float, default=0.0, metavar="DEGREES", help="tilt the camera up or down")
    parser.add_argument("--parallel", action="store_true", help="parallel projection")
    parser.add_argument("--shading", action=argparse.BooleanOptionalAction, default=None,
                        help="Blinn-Phong shading (default: the preset's)")
    parser.add_argument("--background", nargs=3, type=float, default=(0.0, 0.0, 0.0), metavar=("R", "G", "B"),
                        help="background colour, 0-1 or 0-255 (default black)")
    parser.add_argument("--frames", type=int, default=0, metavar="N",
                        help="also render N frames while turning the camera and report frame times")
    parser.add_argument("--iso", type=float, help="isovalue of surface modes (volume units, e.g. HU)")
    parser.add_argument("--sample-distance", type=float, metavar="MM",
                        help="distance between samples along rays, ours and VTK's (default half the smallest "
                             "voxel spacing)")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_cut_arguments(parser)
    add_mode_option_flags(parser, modes())


def _check_surface_isovalue(mode, item, iso) -> None:
    """Surface modes of a volume: refuse an isovalue outside the data's range before rendering anything."""
    volume = getattr(item, "volume", None)
    if not mode.capabilities.uses_iso or volume is None:
        return
    from ..meshing import check_isovalue
    from ..volume import default_iso

    if iso is None:
        iso = item.iso if hasattr(item, "role") else default_iso(volume)
    check_isovalue(volume, float(iso))


def _check_surface_drawn(mode, item, report) -> None:
    """Surface modes: an empty surface, or one that draws no pixel (all its triangles without area), is an error
    before the PNG is written."""
    import numpy as np

    if mode.output != "surface" or not hasattr(item, "volume"):
        return
    from ..meshing import EmptySurfaceError, source_name

    volume, iso = item.volume, report.info["iso"]
    units = volume.units_label
    triangles = int(report.info.get("surface", {}).get("triangles", 0))
    background = np.rint(np.asarray(report.info.get("background", (0.0, 0.0, 0.0))) * 255.0)
    drawn = np.any(np.abs(report.image.astype(np.int16) - background.astype(np.int16)) > 1)
    if triangles and drawn:
        return
    lo, hi = volume.value_range
    reason = "there is none" if not triangles else "its triangles have no area (or are smaller than a pixel)"
    raise EmptySurfaceError(f"{source_name(volume)}: no surface to draw at {iso:g} {units}: {reason}; the values run "
                            f"from {lo:g} to {hi:g} {units}; nothing was written; choose another isovalue")


def run(args) -> int:
    from ..modes import get_mode
    from ..pipeline.headless import RenderSettings, parse_background, render_item
    from ..pipeline.offscreen import write_png

    output = refuse_existing(args.output, args.force)
    if output.suffix.lower() != ".png":
        raise ValueError(f"{output}: pictures are written as PNG; use a .png file name")
    mode = get_mode(args.mode)
    options = mode.resolve_options(mode_options_from_args(args))  # refuses flags the mode does not take, early
    tools = tools_from_args(args)  # bad specifications are refused before loading anything
    item = load_item(args)
    _check_surface_isovalue(mode, item, args.iso)
    if tools and not mode.capabilities.accepts_cutaways:
        from ..modes import modes

        raise ValueError(f"mode {mode.name!r} does not honour cut-away tools (--cut); modes that do: "
                         + ", ".join(m.name for m in modes() if m.capabilities.accepts_cutaways))
    settings = RenderSettings(
        mode=mode, options={k: v for k, v in options.items() if v is not None and k in
                                 mode_options_from_args(args)},
        preset=args.preset, size=tuple(args.size), view=args.view, azimuth=args.azimuth, elevation=args.elevation,
        parallel=args.parallel, shading=args.shading, background=parse_background(args.background),
        frames=args.frames, iso=args.iso, sample_distance=args.sample_distance, tools=tuple(tools),
        cut_evaluation=args.cut_eval,
    )
    report = render_item(item, settings)
    report.info["background"] = list(settings.background)
    _check_surface_drawn(mode, item, report)
    del report.info["background"]
    write_png(report.image, output, overwrite=args.force)
    report.info["output"] = str(output)
    if args.json:
        print_json(report.info)
        return 0
    info = report.info
    timing = (f"median frame {info['frame_seconds'] * 1000:.1f} ms over {info['frames']} frames, "
              f"set-up {info['setup_seconds']:.3f} s" if "frame_seconds" in info
              else f"set-up and first frame {info['setup_seconds']:.3f} s")
    preset = f", {info['preset']}" if "preset" in info else ""
    print(f"Wrote {output} ({args.mode}{preset}, {info['size'][0]}x{info['size'][1]}; {timing})")
    return 0
