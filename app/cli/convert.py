"""``voxelscope convert``: write a volume (any readable format, a DICOM folder) as NIfTI, NRRD, MetaImage or VTI."""

from __future__ import annotations

from .common import add_input_arguments, load_volume_argument

NAME = "convert"
HELP = "write a volume as NIfTI, NRRD, MetaImage or VTI (LPS geometry kept)"
ORDER = 40


def add_arguments(parser) -> None:
    add_input_arguments(parser)
    parser.add_argument("-o", "--output", required=True, help=".nii, .nii.gz, .nrrd, .mha, .mhd or .vti")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")


def run(args) -> int:
    from ..io import save_volume

    volume = load_volume_argument(args)
    path = save_volume(volume, args.output, overwrite=args.force)
    print(f"Wrote {path} ({' x '.join(map(str, volume.dimensions))} voxels, LPS geometry kept)")
    return 0
