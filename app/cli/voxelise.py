"""``voxelscope voxelise``: a closed surface mesh to a mask volume (NIfTI, NRRD, MetaImage or VTI).

``voxelscope voxelise MESH (--grid N | --like VOLUME | --spacing SX SY SZ) [--padding VOXELS]
[--inside parity|winding] -o MASK [--json]`` runs the "voxelise" operation (:mod:`app.operations.voxelise`), the
same the window's Operations menu runs, and writes the mask with the grid's LPS geometry, so a reader finds every
voxel centre where it was.
"""

from __future__ import annotations

import sys

from .common import field_output, like_item, mesh_item, print_json, progress_printer

NAME = "voxelise"
HELP = "turn a closed surface mesh into a mask volume (parity or winding number), written as NIfTI/NRRD/MHA/VTI"
ORDER = 25


def add_arguments(parser) -> None:
    from ..operations.voxelise import DEFAULT_GRID

    parser.add_argument("mesh", help="surface mesh: STL, OBJ, PLY, VTP or OFF (also gzipped), LPS mm")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--grid", type=int, metavar="N",
                       help=f"N voxels along the mesh's longest side, cubic voxels (e.g. {DEFAULT_GRID})")
    where.add_argument("--like", metavar="VOLUME",
                       help="use exactly this volume's grid: dimensions, spacing, origin and direction ('sample' "
                            "for the bundled CT)")
    where.add_argument("--spacing", nargs=3, type=float, metavar=("SX", "SY", "SZ"), help="voxel size in mm")
    parser.add_argument("--padding", type=int, default=2, metavar="VOXELS",
                        help="voxels of margin around the mesh's bounding box with --grid or --spacing (default 2)")
    parser.add_argument("--inside", choices=("parity", "winding"), default="parity",
                        help="inside rule: parity of row crossings (default; closed meshes) or the generalised "
                             "winding number (meshes with holes or self-intersections)")
    parser.add_argument("-o", "--output", required=True, help="mask file: .nii.gz, .nii, .nrrd, .mha or .vti")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args) -> int:
    from ..io import save_volume
    from ..operations import get_operation

    output = field_output(args, "a mask")
    mesh = mesh_item(args.mesh, "voxelise")
    items = {"mesh": mesh, "like": like_item(args)}
    operation = get_operation("voxelise")
    options = operation.resolve_options({
        "grid": args.grid, "padding": args.padding, "inside": args.inside,
        "spacing": " ".join(map(repr, args.spacing)) if args.spacing else None,
    })

    result = operation.run(items, options, progress=progress_printer("voxelise", args))
    if not args.json and sys.stderr.isatty():
        print(file=sys.stderr)
    written = save_volume(result.item.volume, output, overwrite=args.force)
    report = {**result.report, "output": str(written)}
    for warning in report["warnings"]:
        print(f"voxelscope: warning: {warning}", file=sys.stderr)
    if args.json:
        print_json(report)
        return 0
    dims = " x ".join(map(str, report["dimensions"]))
    spacing = " x ".join(f"{s:.4g}" for s in report["spacing"])
    mesh_volume = report["mesh_volume_mm3"]
    print(f"Voxelised {mesh.name} ({report['mesh']['triangles']:,} triangles) by {report['rule']} on {dims} voxels of "
          f"{spacing} mm in {report['seconds']:.3f} s")
    print(f"Inside: {report['inside_voxels']:,} voxels, {report['volume_mm3']:.6g} mm^3 (mesh: {mesh_volume:.6g} mm^3, "
          f"{report['mesh_volume_measured_on']})")
    print(f"Wrote {written} (uint8 mask, LPS geometry of the grid)")
    return 0
