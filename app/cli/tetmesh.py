"""``voxelscope tetmesh``: fill an isosurface with tetrahedra (isosurface stuffing, or VTK's tetrahedralisations)
and write VTU, Gmsh .msh, MEDIT .mesh or Abaqus .inp with a JSON sidecar."""

from __future__ import annotations

from .common import add_input_arguments, load_volume_argument, print_json

NAME = "tetmesh"
HELP = "fill an isosurface with tetrahedra and write VTU, MSH, MESH or INP (with a JSON sidecar)"
ORDER = 25


def add_arguments(parser) -> None:
    from ..operations.tetrahedra import METHODS

    add_input_arguments(parser)
    parser.add_argument("--iso", type=float, help="isovalue in the volume's units (default: 300 HU for CT, else 35 %% "
                                                   "into the value range)")
    parser.add_argument("--h", type=float, metavar="MM", help="lattice spacing of stuffing in mm (default: twice the "
                                                               "smallest voxel spacing)")
    parser.add_argument("--alpha", default="10.7", choices=("10.7", "8.9"),
                        help="stuffing's parameter pair by its angle bound: 10.7 (angles in [10.7, 164.8] degrees, "
                             "default) or 8.9 ([8.9, 158.8])")
    parser.add_argument("--method", default="stuffing", choices=METHODS,
                        help="stuffing (ours, default), vtk-delaunay or vtk-clip-tets")
    parser.add_argument("--inside", default="above", choices=("above", "below"),
                        help="inside is at or above the isovalue (default) or at or below it (distance fields that "
                             "are negative inside)")
    parser.add_argument("-o", "--output", required=True, help="output file: .vtu, .msh (Gmsh), .mesh (MEDIT) or .inp "
                                                               "(Abaqus)")
    parser.add_argument("--force", action="store_true", help="replace existing output files")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args) -> int:
    from ..io.tetmesh import check_targets, tetmesh_provenance, write_tetmesh
    from ..operations.tetrahedra import tetrahedralise
    from ..scene import FieldItem, VolumeItem

    targets = check_targets(args.output, overwrite=args.force)  # before any work
    volume = load_volume_argument(args)
    if args.h is not None and not args.h > 0:
        raise ValueError(f"--h must be a positive number of mm, got {args.h}")
    source = FieldItem("input", volume=volume, role="distance") if args.inside == "below" else \
        VolumeItem("input", volume=volume)
    result = tetrahedralise(source, method=args.method, iso=args.iso, h=args.h, alpha=args.alpha, conformity=True)
    sidecar = tetmesh_provenance(volume, result, output=targets[0])
    written = write_tetmesh(result.mesh, targets[0], overwrite=args.force, sidecar=sidecar,
                            min_angles=result.min_angles)
    q = result.quality
    report = {
        "tetrahedra": result.mesh.n_tetrahedra,
        "points": result.mesh.n_points,
        "min_dihedral_deg": q["min_dihedral_deg"],
        "max_dihedral_deg": q["max_dihedral_deg"],
        "seconds": result.seconds,
        **result.parameters,
        "quality": q,
        "stats": result.stats,
        "output": str(written[0]),
        "sidecar": str(written[1]),
    }
    if args.json:
        print_json(report)
        return 0
    print(f"{report['tetrahedra']:,} tetrahedra, {report['points']:,} points, dihedral angles "
          f"{q['min_dihedral_deg']:.2f} to {q['max_dihedral_deg']:.2f} degrees, conforming={q.get('conforming')}, "
          f"in {result.seconds.get('total', 0.0):.2f} s ({args.method})")
    print(f"Wrote {written[0]} and {written[1]}")
    return 0
