"""The ``voxelscope`` command line.

Subcommands share the headless logic the workbench uses (``app.io``, ``app.meshing``, ``app.render_job``,
``app.bench``). Errors end the program with a non-zero exit status and one clear line on stderr; ``--debug`` shows
the traceback instead.

The desktop front end is found through the ``voxelscope.frontends`` entry point (provided by the ``ui`` package),
so this Qt-free layer never imports the user interface.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from importlib import import_module
from pathlib import Path
from typing import Any, Sequence

EXIT_ERROR = 1
EXIT_USAGE = 2


class CommandError(Exception):
    """An error whose message is shown to the user as it is."""


def _add_volume_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", help="volume file or DICOM folder; 'sample' for the bundled CT phantom, "
                                     "'sample:mri' for the bundled brain MRI")
    parser.add_argument("--series", metavar="UID", help="DICOM SeriesInstanceUID to load (default: the largest stack)")
    parser.add_argument("--strict-spacing", action="store_true",
                        help="refuse DICOM series with missing slices or uneven spacing instead of resampling")
    raw = parser.add_argument_group("raw files (no header)")
    raw.add_argument("--raw-dims", nargs=3, type=int, metavar=("NX", "NY", "NZ"), help="voxels along x, y, z")
    raw.add_argument("--raw-dtype", default="uint8", help="voxel type, e.g. uint8, int16, float32 (default uint8)")
    raw.add_argument("--raw-spacing", nargs=3, type=float, default=(1.0, 1.0, 1.0), metavar=("SX", "SY", "SZ"),
                     help="voxel size in mm (default 1 1 1)")
    raw.add_argument("--raw-endian", choices=("little", "big"), default="little")
    raw.add_argument("--raw-header", type=int, default=0, metavar="BYTES", help="bytes to skip at the start")


def _load(args):
    from .io import RawLayout, load_volume
    from .samples import resolve_path

    path = resolve_path(args.path)
    raw = None
    if args.raw_dims:
        raw = RawLayout(tuple(args.raw_dims), args.raw_dtype, tuple(args.raw_spacing), byte_order=args.raw_endian,
                        header_bytes=args.raw_header)
    return load_volume(path, series_uid=args.series, raw=raw, irregular="error" if args.strict_spacing else "resample")


def _print_json(data: dict[str, Any]) -> None:
    print(json.dumps(data, indent=2, default=str))


# ------------------------------------------------------------------------------------------------------------
# info
# ------------------------------------------------------------------------------------------------------------
def _info(args) -> int:
    volume = _load(args)
    facts = volume.describe()
    if volume.metadata.get("series_uid"):
        facts["series_uid"] = volume.metadata["series_uid"]
    if "other_series" in volume.metadata:
        facts["other_series"] = volume.metadata["other_series"]
    if args.json:
        _print_json(facts)
        return 0
    units = volume.units_label
    lines = [
        f"Source       {volume.metadata.get('source_path', args.path)} ({facts['source_format']})",
        f"Dimensions   {' x '.join(map(str, facts['dimensions']))} voxels (x, y, z)",
        f"Spacing      {' x '.join(f'{s:g}' for s in facts['spacing'])} mm",
        f"Origin       ({', '.join(f'{o:.3f}' for o in facts['origin'])}) mm LPS",
        "Direction    " + "  ".join(
            "(" + ", ".join(f"{v:+.4f}" for v in volume.direction[:, c]) + f") {label}"
            for c, label in zip(range(3), ("i", "j", "k"))
        ) + f"   axes point to {'/'.join(volume.axis_labels())}",
        f"Bounds       x {facts['world_bounds'][0]:.2f} to {facts['world_bounds'][1]:.2f}, "
        f"y {facts['world_bounds'][2]:.2f} to {facts['world_bounds'][3]:.2f}, "
        f"z {facts['world_bounds'][4]:.2f} to {facts['world_bounds'][5]:.2f} mm LPS",
        f"Values       {facts['dtype']}, {facts['range'][0]:g} to {facts['range'][1]:g} {units}",
        f"Modality     {facts['modality'] or 'unknown'}",
    ]
    if facts.get("series_uid"):
        lines.append(f"Series       {facts['series_uid']}  {volume.metadata.get('series_description', '')}".rstrip())
    for other in facts.get("other_series", []):
        lines.append(f"Not used     series {other['series_uid']} ({other['description'] or 'no description'}, "
                     f"{other['slices']} images): {other['reason']}")
    for warning in facts["warnings"]:
        lines.append(f"Warning      {warning}")
    print("\n".join(lines))
    return 0


# ------------------------------------------------------------------------------------------------------------
# mesh
# ------------------------------------------------------------------------------------------------------------
def _mesh(args) -> int:
    from .meshing import default_iso, export_mesh

    volume = _load(args)
    iso = args.iso if args.iso is not None else default_iso(volume)
    cleanup = {}
    if args.smooth:
        cleanup["smooth_iterations"] = args.smooth
        cleanup["smooth_passband"] = args.passband
    if args.decimate:
        cleanup["decimate"] = args.decimate
    if args.largest:
        cleanup["largest_component"] = True
    if args.fill_holes:
        cleanup["fill_holes_mm"] = args.fill_holes
    export = export_mesh(volume, args.output, method=args.method, iso=iso, step=args.step,
                         coordinates=args.coordinates, cleanup=cleanup, close_edges=args.close_edges,
                         overwrite=args.force)
    stats = export.stats
    validity = export.validity or {}
    report = {
        "points": int(stats["points"]),
        "triangles": int(stats["triangles"]),
        "cells": int(stats["cells"]),
        "strips": int(stats["strips"]),
        "bytes": int(stats["bytes"]),
        "seconds": float(stats["seconds"]),
        "compile_seconds": float(stats.get("compile_seconds", 0.0)),
        "method": args.method,
        "iso": iso,
        "iso_units": volume.units_label,
        "coordinates": args.coordinates.upper(),
        "output": str(export.paths[0]),
        "sidecar": str(export.paths[1]) if len(export.paths) > 1 else None,
        "written": {k: int(v) for k, v in export.written.items()},
        "validity": validity,
    }
    if args.json:
        _print_json(report)
        return 0
    print(f"Validity: watertight={validity.get('watertight')}, manifold={validity.get('manifold')}, "
          f"outward normals={validity.get('outward_normals')}, components={validity.get('components')}")
    print(f"Extracted {report['triangles']} triangles, {report['points']} points, {report['strips']} strips, "
          f"{report['bytes']} bytes in {report['seconds']:.3f} s at {iso:g} {volume.units_label}")
    print(f"Wrote {report['output']} ({report['written']['triangles']} triangles, {report['coordinates']} mm) "
          f"and {report['sidecar']}")
    return 0


# ------------------------------------------------------------------------------------------------------------
# render
# ------------------------------------------------------------------------------------------------------------
def _render(args) -> int:
    from .render_job import RenderSettings, options_from_mapping, parse_background, render_volume, write_png

    output = Path(args.output).expanduser()
    if output.exists() and not args.force:
        raise CommandError(f"{output} already exists; choose another name or add --force")
    volume = _load(args)
    options = options_from_mapping(args.mode, {
        "lighting": args.lighting, "samples": args.samples, "light_samples": args.light_samples,
        "slices": args.slices, "compositing": args.compositing,
    })
    settings = RenderSettings(
        mode=args.mode, preset=args.preset, size=tuple(args.size), view=args.view, azimuth=args.azimuth,
        elevation=args.elevation, parallel=args.parallel, shading=args.shading,
        background=parse_background(args.background), frames=args.frames, iso=args.iso,
        sample_distance=args.step, options=options,
    )
    report = render_volume(volume, settings)
    write_png(report.image, output, overwrite=args.force)
    report.info["output"] = str(output)
    if args.json:
        _print_json(report.info)
        return 0
    info = report.info
    timing = (f"median frame {info['frame_seconds'] * 1000:.1f} ms over {info['frames']} frames, "
              f"set-up {info['setup_seconds']:.3f} s" if "frame_seconds" in info
              else f"set-up and first frame {info['setup_seconds']:.3f} s")
    print(f"Wrote {output} ({args.mode}, {info['preset']}, {info['size'][0]}x{info['size'][1]}; {timing})")
    return 0


# ------------------------------------------------------------------------------------------------------------
# bench, convert, series, gui
# ------------------------------------------------------------------------------------------------------------
def _bench(args) -> int:
    from .bench import BENCHMARKS
    from .vtk_setup import configure_vtk

    configure_vtk()
    module = import_module(BENCHMARKS[args.name])
    out_dir = Path(args.output).expanduser()
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    def progress(fraction: float) -> None:
        print(f"\r{args.name}: {100 * fraction:5.1f} %", end="", file=sys.stderr, flush=True)

    written = module.run(out_dir, quick=args.quick, progress=progress)
    print(file=sys.stderr)
    print(f"{args.name}: wrote {len(written)} files to {out_dir} in {time.perf_counter() - start:.1f} s")
    for path in written:
        print(f"  {path}")
    return 0


def _convert(args) -> int:
    from .io import save_volume

    volume = _load(args)
    path = save_volume(volume, args.output, overwrite=args.force)
    print(f"Wrote {path} ({' x '.join(map(str, volume.dimensions))} voxels, LPS geometry kept)")
    return 0


def _series(args) -> int:
    from .io import list_series
    from .samples import resolve_path

    series = list_series(resolve_path(args.folder))
    if args.json:
        _print_json({"series": series})
        return 0
    if not series:
        print("No image series found")
    for item in series:
        print(f"{item['series_uid']}  {item['slices']:4d} images {item['columns']}x{item['rows']}  "
              f"{item['modality'] or '?':3s} {item['description']}")
    return 0


def _gui(args, extra: Sequence[str]) -> int:
    from importlib.metadata import entry_points

    frontends = [ep for ep in entry_points(group="voxelscope.frontends") if ep.name == "gui"]
    if not frontends:
        raise CommandError("the desktop front end is not installed; install Voxelscope with its 'ui' package")
    return int(frontends[0].load()(list(extra)) or 0)


# ------------------------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    from . import __version__
    from .bench import BENCHMARKS
    from .modes import mode_names
    from .transfer import preset_names

    parser = argparse.ArgumentParser(
        prog="voxelscope",
        description="Voxelscope: look at medical and scientific volumes in several render modes, export meshes. "
                    "Without a command, starts the desktop workbench.",
    )
    parser.add_argument("--version", action="version", version=f"Voxelscope {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    info = commands.add_parser("info", help="describe a volume: size, spacing, geometry (LPS), values, series")
    _add_volume_arguments(info)
    info.add_argument("--json", action="store_true", help="print one JSON object")

    mesh = commands.add_parser("mesh", help="extract a surface and write STL, PLY, OBJ or VTP (with a JSON sidecar)")
    _add_volume_arguments(mesh)
    mesh.add_argument("--method", default="flying-edges", choices=mode_names("surface"), help="surface method")
    mesh.add_argument("--iso", type=float, help="isovalue or threshold in the volume's units (default: 300 HU for "
                                                 "CT, else 35 %% into the value range)")
    mesh.add_argument("-o", "--output", required=True, help="output file: .stl (binary), .ply, .obj or .vtp")
    mesh.add_argument("--step", type=int, default=1, help="extract on every STEP-th voxel (preview); default 1")
    mesh.add_argument("--coordinates", default="LPS", type=str.upper, choices=("LPS", "RAS"),
                      help="patient coordinate system of the written points (default LPS)")
    mesh.add_argument("--smooth", type=int, default=0, metavar="ITERATIONS", help="windowed-sinc smoothing iterations")
    mesh.add_argument("--passband", type=float, default=0.1, help="smoothing pass band in (0, 2) (default 0.1)")
    mesh.add_argument("--decimate", type=float, default=0.0, metavar="FRACTION",
                      help="quadric decimation: fraction of triangles to remove, in [0, 1)")
    mesh.add_argument("--largest", action="store_true", help="keep the largest connected component only")
    mesh.add_argument("--fill-holes", type=float, default=0.0, metavar="MM", help="close holes up to this size (mm)")
    mesh.add_argument("--close-edges", action="store_true",
                      help="cap the surface where it leaves the volume (within one voxel outside the data)")
    mesh.add_argument("--force", action="store_true", help="replace existing output files")
    mesh.add_argument("--json", action="store_true", help="print one JSON object")

    render = commands.add_parser("render", help="render a volume off-screen to PNG, optionally timing frames")
    _add_volume_arguments(render)
    render.add_argument("--mode", required=True, choices=mode_names(), help="render mode")
    render.add_argument("-o", "--output", required=True, help="output PNG file")
    render.add_argument("--preset", choices=preset_names(), help="transfer function (default: ct-bone for CT, "
                                                                  "mr-default otherwise)")
    render.add_argument("--size", nargs=2, type=int, default=(512, 512), metavar=("W", "H"), help="pixels (512 512)")
    render.add_argument("--view", default="anterior",
                        choices=("anterior", "posterior", "left", "right", "superior", "inferior"),
                        help="side the camera looks from before turning (default anterior)")
    render.add_argument("--azimuth", type=float, default=0.0, metavar="DEG", help="turn the camera about view up")
    render.add_argument("--elevation", type=float, default=0.0, metavar="DEG", help="tilt the camera up or down")
    render.add_argument("--parallel", action="store_true", help="parallel projection")
    render.add_argument("--shading", action=argparse.BooleanOptionalAction, default=None,
                        help="Blinn-Phong shading (default: the preset's)")
    render.add_argument("--background", nargs=3, type=float, default=(0.0, 0.0, 0.0), metavar=("R", "G", "B"),
                        help="background colour, 0-1 or 0-255 (default black)")
    render.add_argument("--frames", type=int, default=0, metavar="N",
                        help="also render N frames while turning the camera and report frame times")
    render.add_argument("--iso", type=float, help="isovalue of surface modes (volume units)")
    render.add_argument("--step", type=float, metavar="MM", help="sample distance along rays in mm "
                                                                  "(default half the smallest spacing)")
    render.add_argument("--lighting", choices=("emission", "phong", "scatter"), help="ray-marching lighting model")
    render.add_argument("--samples", type=int, metavar="N", help="ray marching: samples across the volume "
                                                                 "(instead of --step)")
    render.add_argument("--light-samples", type=int, metavar="M", help="ray marching: samples towards the light")
    render.add_argument("--slices", type=int, metavar="K", help="texture slicing: number of slices (default: one "
                                                                 "per smallest voxel spacing along the view)")
    render.add_argument("--compositing", choices=("float", "uint8", "gl"),
                        help="texture slicing: accumulate in float (default), in 8 bits, or draw with OpenGL")
    render.add_argument("--force", action="store_true", help="replace an existing output file")
    render.add_argument("--json", action="store_true", help="print one JSON object")

    bench = commands.add_parser("bench", help="run a benchmark against VTK's built-ins; writes CSV and plots")
    bench.add_argument("name", choices=list(BENCHMARKS), help="benchmark")
    bench.add_argument("-o", "--output", required=True, help="output folder")
    bench.add_argument("--quick", action="store_true", help="a smaller run that finishes in a few minutes")

    convert = commands.add_parser("convert", help="write a volume as NIfTI, NRRD, MetaImage or VTI")
    _add_volume_arguments(convert)
    convert.add_argument("-o", "--output", required=True, help=".nii, .nii.gz, .nrrd, .mha, .mhd or .vti")
    convert.add_argument("--force", action="store_true", help="replace an existing output file")

    series = commands.add_parser("series", help="list the DICOM image series in a folder")
    series.add_argument("folder")
    series.add_argument("--json", action="store_true", help="print one JSON object")

    commands.add_parser("gui", help="start the desktop workbench (also the default); 'voxelscope gui --help' for options",
                        add_help=False)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    if debug:
        argv.remove("--debug")
    # Everything after "gui" (or no command at all) belongs to the front end's own parser.
    if not argv or argv[0] == "gui" or (argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version")):
        extra = argv[1:] if argv and argv[0] == "gui" else argv
        return _run(lambda: _gui(None, extra), debug)
    parser = build_parser()
    args = parser.parse_args(argv)
    handlers = {"info": _info, "mesh": _mesh, "render": _render, "bench": _bench, "convert": _convert,
                "series": _series}
    return _run(lambda: handlers[args.command](args), debug)


def _run(action, debug: bool) -> int:
    from algorithms._progress import OperationCancelled
    from algorithms._vtk import VTKError

    from .io.errors import VolumeReadError, VolumeWriteError
    from .vtk_setup import configure_vtk

    configure_vtk()
    try:
        return action()
    except KeyboardInterrupt:
        print("voxelscope: interrupted", file=sys.stderr)
        return 130
    except (CommandError, VolumeReadError, VolumeWriteError, ValueError, OperationCancelled, VTKError, OSError) as exc:
        if debug:
            raise
        message = str(exc) if not isinstance(exc, OSError) or not exc.filename else f"{exc.filename}: {exc.strerror}"
        print(f"voxelscope: error: {message}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
