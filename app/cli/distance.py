"""``voxelscope distance``: a mesh's signed distance field (mm, negative inside) written as NIfTI, NRRD, MetaImage
or VTI.

``voxelscope distance MESH (--grid N | --like VOLUME | --spacing SX SY SZ) [--band D|P%] [--outside
clamp|propagate] [--inside parity|winding] -o FIELD [--json]`` runs the "distance" operation
(:mod:`app.operations.distance`), the same the window's Operations menu runs. The JSON report holds the grid,
``band_mm``, ``seconds`` (``sign``, ``band``, ``outside``, ``total``) and the value range.
"""

from __future__ import annotations

from .common import (add_grid_arguments, field_output, grid_from_args, like_item, mesh_item, print_json,
                     run_operation)

NAME = "distance"
HELP = "a mesh's signed distance field (mm, negative inside), exact in a band, written as NIfTI/NRRD/MHA/VTI"
ORDER = 26


def add_distance_arguments(parser, *, required: bool = True) -> None:
    """The grid flags and the distance field's own (band, outside, inside); shared with ``voxelscope csg``."""
    add_grid_arguments(parser, padding=4, required=required)
    parser.add_argument("--band", default="10%", metavar="D|P%",
                        help="width of the exact band: mm (e.g. 3) or per cent of the mesh's height (e.g. 5%%; "
                             "default 10%%)")
    parser.add_argument("--outside", choices=("clamp", "propagate"), default="clamp",
                        help="outside the band: clamp to +-band (default) or propagate exact distances to the "
                             "nearest triangles over the whole grid")
    parser.add_argument("--inside", choices=("parity", "winding"), default="parity",
                        help="sign by voxelisation: parity (default; closed meshes) or winding number (holes)")


def add_arguments(parser) -> None:
    parser.add_argument("mesh", help="surface mesh: STL, OBJ, PLY, VTP or OFF (also gzipped), LPS mm")
    add_distance_arguments(parser)
    parser.add_argument("-o", "--output", required=True, help="field file: .nii.gz, .nii, .nrrd, .mha or .vti")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def distance_options(args) -> dict:
    return {**grid_from_args(args), "band": args.band, "outside": args.outside, "inside": args.inside}


def run(args) -> int:
    from ..io import save_volume
    from ..operations import get_operation

    output = field_output(args, "a distance field")
    items = {"mesh": mesh_item(args.mesh, "distance"), "like": like_item(args)}
    result = run_operation("distance", items, get_operation("distance").resolve_options(distance_options(args)), args)
    written = save_volume(result.item.volume, output, overwrite=args.force)
    report = {**result.report, "seconds": result.report["timing"], "output": str(written)}
    report.pop("timing")
    if args.json:
        print_json(report)
        return 0
    dims = " x ".join(map(str, report["dimensions"]))
    s = report["seconds"]
    low, high = report["value_range_mm"]
    print(f"Distance field of {items['mesh'].name} ({report['triangles']:,} triangles) on {dims} voxels, band "
          f"{report['band_mm']:.4g} mm, outside {report['outside']}: {s['total']:.2f} s (sign {s['sign']:.2f}, band "
          f"{s['band']:.2f}, outside {s['outside']:.2f})")
    print(f"Values {low:.4g} to {high:.4g} mm (negative inside); wrote {written}")
    return 0
