"""``voxelscope render``: one off-screen picture of any mode (the same view pipeline as the window), optionally
timing frames while the camera turns."""

from __future__ import annotations

import argparse

from .common import (add_input_arguments, add_mode_option_flags, load_item, mode_options_from_args, print_json,
                     refuse_existing)

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
    add_mode_option_flags(parser, modes())


def run(args) -> int:
    from ..modes import get_mode
    from ..pipeline.headless import RenderSettings, parse_background, render_item
    from ..pipeline.offscreen import write_png

    output = refuse_existing(args.output, args.force)
    if output.suffix.lower() != ".png":
        raise ValueError(f"{output}: pictures are written as PNG; use a .png file name")
    mode = get_mode(args.mode)
    options = mode.resolve_options(mode_options_from_args(args))  # refuses flags the mode does not take, early
    item = load_item(args)
    settings = RenderSettings(
        mode=args.mode, options={k: v for k, v in options.items() if v is not None and k in
                                 mode_options_from_args(args)},
        preset=args.preset, size=tuple(args.size), view=args.view, azimuth=args.azimuth, elevation=args.elevation,
        parallel=args.parallel, shading=args.shading, background=parse_background(args.background),
        frames=args.frames, iso=args.iso, sample_distance=args.sample_distance,
    )
    report = render_item(item, settings)
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
