"""``voxelscope mesh``: extract a surface with any surface mode and write STL, PLY, OBJ or VTP with a JSON sidecar."""

from __future__ import annotations

from .common import (add_input_arguments, add_mode_option_flags, load_volume_argument, mode_options_from_args,
                     print_json)

NAME = "mesh"
HELP = "extract a surface and write STL, PLY, OBJ or VTP (with a JSON sidecar)"
ORDER = 20


def add_arguments(parser) -> None:
    from ..modes import get_mode, mode_names

    surface_modes = mode_names(input="volume", output="surface")
    add_input_arguments(parser)
    parser.add_argument("--method", default="flying-edges", choices=surface_modes, help="surface method")
    parser.add_argument("--iso", type=float, help="isovalue or threshold in the volume's units (default: 300 HU for "
                                                   "CT, else 35 %% into the value range)")
    parser.add_argument("-o", "--output", required=True, help="output file: .stl (binary), .ply, .obj or .vtp")
    parser.add_argument("--stride", type=int, default=1, metavar="VOXELS",
                        help="extract on every STRIDE-th voxel (a quick preview; methods with a coarse path only); "
                             "default 1")
    parser.add_argument("--coordinates", default="LPS", type=str.upper, choices=("LPS", "RAS"),
                        help="patient coordinate system of the written points (default LPS)")
    parser.add_argument("--smooth", type=int, default=0, metavar="ITERATIONS", help="windowed-sinc smoothing iterations")
    parser.add_argument("--passband", type=float, default=0.1, help="smoothing pass band in (0, 2) (default 0.1)")
    parser.add_argument("--decimate", type=float, default=0.0, metavar="FRACTION",
                        help="quadric decimation: fraction of triangles to remove, in [0, 1)")
    parser.add_argument("--largest", action="store_true", help="keep the largest connected component only")
    parser.add_argument("--fill-holes", type=float, default=0.0, metavar="MM", help="close holes up to this size (mm)")
    parser.add_argument("--close-edges", action="store_true",
                        help="cap the surface where it leaves the volume (within one voxel outside the data)")
    parser.add_argument("--force", action="store_true", help="replace existing output files")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_mode_option_flags(parser, [get_mode(name) for name in surface_modes])


def run(args) -> int:
    from ..meshing import default_iso, export_mesh
    from ..modes import get_mode

    options = get_mode(args.method).resolve_options(mode_options_from_args(args))
    volume = load_volume_argument(args)
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
    export = export_mesh(volume, args.output, method=args.method, iso=iso, stride=args.stride, options=options,
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
        "options": options,
        "iso": iso,
        "iso_units": volume.units_label,
        "coordinates": args.coordinates.upper(),
        "output": str(export.paths[0]),
        "sidecar": str(export.paths[1]) if len(export.paths) > 1 else None,
        "written": {k: int(v) for k, v in export.written.items()},
        "validity": validity,
    }
    if args.json:
        print_json(report)
        return 0
    print(f"Validity: watertight={validity.get('watertight')}, manifold={validity.get('manifold')}, "
          f"outward normals={validity.get('outward_normals')}, components={validity.get('components')}")
    print(f"Extracted {report['triangles']} triangles, {report['points']} points, {report['strips']} strips, "
          f"{report['bytes']} bytes in {report['seconds']:.3f} s at {iso:g} {volume.units_label}")
    print(f"Wrote {report['output']} ({report['written']['triangles']} triangles, {report['coordinates']} mm) "
          f"and {report['sidecar']}")
    return 0
