"""``voxelscope mesh``: extract a surface with any surface mode and write STL, PLY, OBJ or VTP with a JSON sidecar."""

from __future__ import annotations

from .common import (CommandError, add_cleanup_arguments, add_cut_arguments, add_input_arguments, add_mode_option_flags,
                     cleanup_from_args, load_volume_argument, mode_options_from_args, print_json, terminal_progress,
                     tools_from_args)

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
    add_cleanup_arguments(parser)
    parser.add_argument("--close-edges", action="store_true",
                        help="cap the surface where it leaves the volume (within one voxel outside the data)")
    parser.add_argument("--force", action="store_true",
                        help="replace existing output files, and export surfaces of more than 20 M triangles")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_cut_arguments(parser)
    # Chunked volumes (issue 19): a Zarr/OME-Zarr store meshed chunk by chunk on a Dask cluster.
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--workers", type=int, nargs="?", const=-1, metavar="N",
                         help="mesh a .zarr chunk by chunk on a local Dask cluster of N worker processes (default: "
                              "the machine's cores)")
    cluster.add_argument("--scheduler", metavar="ADDRESS", help="mesh a .zarr chunk by chunk on the Dask cluster of "
                                                                "this scheduler (e.g. tcp://10.0.0.5:8786)")
    # Label volumes (issue 18): one closed mesh per label into the folder -o, listed in -o/labels.json.
    parser.add_argument("--labels", metavar="all|1,5,9", help="the input is a label volume: write one closed mesh "
                                                              "per label (all, or the labels listed) into the folder -o")
    parser.add_argument("--color-table", metavar="FILE", help="with --labels: label names and colours (ITK-SNAP, 3D "
                                                              "Slicer, FreeSurfer, AAL or MRIcron file)")
    parser.add_argument("--format", default="stl", choices=("stl", "ply", "obj", "vtp"),
                        help="with --labels: mesh file format (default stl)")
    add_mode_option_flags(parser, [get_mode(name) for name in surface_modes])


def run(args) -> int:
    from algorithms.common.progress import scaled

    from ..mesh_files import check_mesh_targets
    from ..meshing import surface_for_export, write_export
    from ..volume import default_iso
    from ..modes import get_mode

    options = get_mode(args.method).resolve_options(mode_options_from_args(args))
    tools = tools_from_args(args)  # bad specifications are refused before loading anything
    cleanup = cleanup_from_args(args)
    if args.workers is not None or args.scheduler is not None:
        from ._mesh_chunked import run_chunked_mesh  # dask and distributed: imported only when asked for

        with terminal_progress(f"mesh {args.output}", quiet=args.json) as progress:
            return run_chunked_mesh(args, tools, cleanup, progress=progress)
    volume = load_volume_argument(args)
    if args.labels is not None:
        if tools:
            raise CommandError("--cut applies to one surface, not to --labels; cut the label volume first with "
                               "'voxelscope convert --cut'")
        return _label_meshes(volume, args, options, cleanup)
    iso = args.iso if args.iso is not None else default_iso(volume)
    cut = None
    if tools:
        import time

        from ..meshing import check_isovalue
        from ..cutaways import cut_for_surface, describe_tools

        check_isovalue(volume, iso)  # on the data, before the cut lowers values
        start = time.perf_counter()
        # The surface of the data minus the tools, capped at the cut (CSG difference, source 002, 3.3.1).
        volume = cut_for_surface(volume, tools, iso, evaluation=args.cut_eval)
        cut = describe_tools(tools, args.cut_eval, time.perf_counter() - start)
    output = check_mesh_targets(args.output, overwrite=args.force)  # before any work
    with terminal_progress(f"mesh {output.name}", quiet=args.json) as progress:
        surface = surface_for_export(volume, method=args.method, iso=iso, stride=args.stride, options=options,
                                     coordinates=args.coordinates, close_edges=args.close_edges,
                                     allow_large=args.force, progress=scaled(progress, 0.0, 0.4))
        units = volume.units_label
        del volume  # the samples are not needed any more: clean-up and validation get their memory
        export = write_export(surface, output, cleanup=cleanup, overwrite=args.force,
                              progress=scaled(progress, 0.4, 1.0))
        del surface
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
        "iso_units": units,
        "coordinates": args.coordinates.upper(),
        "output": str(export.paths[0]),
        "sidecar": str(export.paths[1]) if len(export.paths) > 1 else None,
        "written": {k: int(v) for k, v in export.written.items()},
        "validity": validity,
    }
    if cut is not None:
        report["cut"] = cut
    if args.json:
        print_json(report)
        return 0
    print(f"Validity: watertight={validity.get('watertight')}, manifold={validity.get('manifold')}, "
          f"outward normals={validity.get('outward_normals')}, components={validity.get('components')}")
    print(f"Extracted {report['triangles']} triangles, {report['points']} points, {report['strips']} strips, "
          f"{report['bytes']} bytes in {report['seconds']:.3f} s at {iso:g} {units}")
    print(f"Wrote {report['output']} ({report['written']['triangles']} triangles, {report['coordinates']} mm) "
          f"and {report['sidecar']}")
    return 0


def _label_meshes(volume, args, options: dict, cleanup) -> int:
    """``voxelscope mesh LABELS --labels all|1,5,9 -o DIR [--json]``: one closed mesh per label, listed in
    ``DIR/labels.json``."""
    from pathlib import Path

    from ..labels import export_label_meshes, table_for

    table = table_for(volume, args.color_table)
    with terminal_progress(f"mesh {args.output}", quiet=args.json) as progress:
        listing = export_label_meshes(volume, args.output, labels=args.labels, table=table, method=args.method,
                                      suffix="." + args.format, coordinates=args.coordinates, cleanup=cleanup,
                                      options=options, overwrite=args.force, progress=progress)
    listing["folder"] = str(Path(args.output).expanduser())
    if args.json:
        print_json(listing)
        return 0
    for mesh in listing["meshes"]:
        print(f"{mesh['label']:>5}  {mesh['name'][:40]:<40} {mesh['voxel_volume_mm3']:>12.1f} mm^3 of voxels, "
              f"mesh {mesh['mesh_volume_mm3']:.1f} mm^3, watertight={mesh['watertight']}  {mesh['file']}")
    print(f"Wrote {len(listing['meshes'])} meshes and labels.json to {listing['folder']} "
          f"({listing['coordinate_system']} mm, {listing['seconds']:.1f} s)")
    return 0
