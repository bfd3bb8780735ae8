"""``voxelscope csg``: union, intersection or difference of meshes, distance fields and volumes' isosurfaces,
written as a mesh (marching cubes of the result, checked) or as the distance field.

``voxelscope csg A (--union|--intersect|--subtract) B [C ...] (--grid N | --like VOLUME | --spacing SX SY SZ)
-o OUT.(stl|ply|obj|vtp|nii.gz|nrrd|mha|vti) [--blend MM] [--offset MM] [--json]`` runs the "csg" operation
(:mod:`app.operations.distance`). The JSON report gives ``seconds`` for the inputs' fields, the boolean and the
meshing separately, and the validity report of a mesh output.
"""

from __future__ import annotations

import time

from .common import CommandError, like_item, print_json, refuse_existing, run_operation
from .distance import add_distance_arguments, distance_options

NAME = "csg"
HELP = "union, intersection or difference of meshes, distance fields and volumes; writes a mesh or the field"
ORDER = 27


def add_arguments(parser) -> None:
    parser.add_argument("first", metavar="A", help="a mesh (STL, OBJ, PLY, VTP, OFF), a distance field or mask, or a "
                                                   "volume (its isosurface at --iso)")
    parser.add_argument("others", metavar="B", nargs="+", help="one to three more solids, as A")
    how = parser.add_mutually_exclusive_group(required=True)
    how.add_argument("--union", dest="operation", action="store_const", const="union", help="A or B")
    how.add_argument("--intersect", dest="operation", action="store_const", const="intersection", help="A and B")
    how.add_argument("--subtract", dest="operation", action="store_const", const="difference",
                     help="A minus B (and minus C ...)")
    add_distance_arguments(parser, required=False)
    parser.add_argument("--blend", type=float, default=0.0, metavar="MM",
                        help="blend radius of the smooth variant in mm (default 0: sharp)")
    parser.add_argument("--iso", type=float, help="isovalue of volume inputs in their units (default: 300 HU for CT)")
    parser.add_argument("--offset", type=float, default=0.0, metavar="MM",
                        help="mesh the surface this many mm outside (positive) or inside (negative) the result")
    parser.add_argument("-o", "--output", required=True,
                        help="a mesh (.stl, .ply, .obj, .vtp) or the field (.nii.gz, .nii, .nrrd, .mha, .vti)")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def _item(text: str, args):
    from ..io.meshes import is_mesh_path, load_mesh
    from ..samples import resolve_path
    from ..scene import FieldItem, MeshItem, VolumeItem
    from .common import _item_name, load_volume_argument

    path = resolve_path(text)
    if is_mesh_path(path):
        return MeshItem.from_mesh(load_mesh(path), _item_name(path))
    volume = load_volume_argument(args, text)
    low, high = (float(v) for v in volume.value_range)
    if volume.modality == "distance" or (volume.units != "HU" and volume.array.dtype.kind == "f" and low < 0 < high):
        # a float field with both signs (not CT): a signed distance field as ``voxelscope distance`` writes it
        return FieldItem(_item_name(path), volume=volume, role="distance")
    if volume.modality == "mask":
        return FieldItem(_item_name(path), volume=volume, role="mask")
    return VolumeItem(_item_name(path), volume=volume)


def run(args) -> int:
    from ..io import WRITABLE_SUFFIXES, save_volume
    from ..mesh_files import MESH_SUFFIXES
    from ..operations import get_operation

    output = refuse_existing(args.output, args.force)
    lower = str(output).lower()
    as_mesh = lower.endswith(MESH_SUFFIXES)
    if not as_mesh and not lower.endswith(WRITABLE_SUFFIXES):
        raise CommandError(f"{output}: write the result as a mesh ({', '.join(MESH_SUFFIXES)}) or a field "
                           f"({', '.join(WRITABLE_SUFFIXES)})")
    if len(args.others) > 3:
        raise CommandError(f"csg combines two to four solids, got {1 + len(args.others)}")
    inputs = [_item(text, args) for text in [args.first, *args.others]]
    items = dict(zip("abcd", inputs))
    items["like"] = like_item(args)
    options = get_operation("csg").resolve_options({**distance_options(args), "operation": args.operation,
                                                    "blend": args.blend, "iso": args.iso})
    result = run_operation("csg", items, options, args)
    report = dict(result.report)
    report["seconds"] = report.pop("timing")
    if as_mesh:
        from ..mesh_cleanup import validity_report
        from ..meshing import write_mesh
        from ..operations.distance import mesh_result

        mesh_item, seconds = mesh_result(result.item, offset_mm=args.offset)
        report["seconds"]["meshing"] = seconds
        tick = time.perf_counter()
        validity = validity_report(mesh_item.polydata)
        report["seconds"]["validity"] = time.perf_counter() - tick
        report["validity"] = validity.as_dict()
        sidecar = {"operation": report["operation"], "inputs": [n["name"] for n in report["inputs"]],
                   "offset_mm": args.offset, "blend_mm": args.blend, "grid": report.get("dimensions"),
                   "coordinates": "LPS mm", "validity": report["validity"]}
        written = write_mesh(mesh_item.polydata, output, overwrite=args.force, sidecar=sidecar)
        report["output"] = [str(p) for p in written]
        summary = validity.summary()
    else:
        if args.offset:
            raise CommandError("--offset applies to mesh outputs; a field keeps every offset (mesh it at any level)")
        written = save_volume(result.item.volume, output, overwrite=args.force)
        report["output"] = str(written)
        summary = f"field values {report['value_range_mm'][0]:.4g} to {report['value_range_mm'][1]:.4g} mm"
    if args.json:
        print_json(report)
        return 0
    s = report["seconds"]
    meshing = f", meshing {s['meshing']:.3f} s" if "meshing" in s else ""
    print(f"{report['operation'].capitalize()} of {', '.join(i.name for i in inputs)} on "
          f"{' x '.join(map(str, report['dimensions']))} voxels: boolean {s['boolean']:.3f} s{meshing}")
    print(f"{summary}; wrote {report['output'] if not as_mesh else report['output'][0]}")
    return 0
