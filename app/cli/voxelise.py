"""``voxelscope voxelise``: a closed surface mesh to a mask volume (NIfTI, NRRD, MetaImage or VTI).

``voxelscope voxelise MESH (--grid N | --like VOLUME | --spacing SX SY SZ) [--padding VOXELS]
[--inside parity|winding] -o MASK [--json]`` runs the "voxelise" operation (:mod:`app.operations.voxelise`), the
same the window's Operations menu runs, and writes the mask with the grid's LPS geometry, so a reader finds every
voxel centre where it was.
"""

from __future__ import annotations

from .common import (add_grid_arguments, field_output, grid_from_args, like_item, mesh_item, print_json,
                     run_operation)

NAME = "voxelise"
HELP = "turn a closed surface mesh into a mask volume (parity or winding number), written as NIfTI/NRRD/MHA/VTI"
ORDER = 25


def add_arguments(parser) -> None:
    parser.add_argument("mesh", help="surface mesh: STL, OBJ, PLY, VTP or OFF (also gzipped), LPS mm")
    add_grid_arguments(parser, padding=2)
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
    options = get_operation("voxelise").resolve_options({**grid_from_args(args), "inside": args.inside})
    result = run_operation("voxelise", items, options, args)
    written = save_volume(result.item.volume, output, overwrite=args.force)
    report = {**result.report, "output": str(written)}
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
