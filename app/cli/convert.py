"""``voxelscope convert``: write a volume (any readable format, a DICOM folder) as NIfTI, NRRD, MetaImage or VTI."""

from __future__ import annotations

from .common import add_cut_arguments, add_input_arguments, load_volume_argument, tools_from_args

NAME = "convert"
HELP = "write a volume as NIfTI, NRRD, MetaImage or VTI (LPS geometry kept)"
ORDER = 40


def add_arguments(parser) -> None:
    add_input_arguments(parser)
    parser.add_argument("-o", "--output", required=True, help=".nii, .nii.gz, .nrrd, .mha, .mhd, .vti or .zarr "
                                                              "(OME-Zarr with a pyramid)")
    # OME-Zarr output (issue 19): chunked storage for volumes meshed chunk by chunk ('voxelscope mesh --workers').
    parser.add_argument("--chunks", type=int, default=128, metavar="SAMPLES",
                        help="with .zarr: chunk edge in samples (default 128)")
    parser.add_argument("--compressor", default="blosc-zstd", choices=("blosc-zstd", "blosc-lz4", "zstd", "none"),
                        help="with .zarr: chunk compressor (default blosc-zstd)")
    parser.add_argument("--levels", type=int, metavar="N",
                        help="with .zarr: pyramid levels (default: halve until the largest side is <= 128 samples)")
    parser.add_argument("--zarr-format", type=int, default=2, choices=(2, 3),
                        help="with .zarr: Zarr v2 + OME-NGFF 0.4 (default) or Zarr v3 + OME-NGFF 0.5")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_cut_arguments(parser)


def run(args) -> int:
    from ..io import save_volume

    tools = tools_from_args(args)
    volume = load_volume_argument(args)
    cut = None
    if tools:
        import time

        from ..cutaways import cropped_volume, describe_tools, masked_volume

        start = time.perf_counter()
        # keep tools: the region they leave, cropped to its voxels on the volume's grid (3D Slicer's ROI crop);
        # remove tools: the removed voxels set to the volume's minimum (the background).
        if any(tool.mode == "keep" for tool in tools):
            volume = cropped_volume(volume, tools)
        else:
            volume = masked_volume(volume, tools)
        cut = describe_tools(tools, "binary", time.perf_counter() - start)
    if str(args.output).lower().rstrip("/").endswith(".zarr"):
        from ..io.zarr import save_zarr

        if args.chunks < 8:
            from .common import CommandError

            raise CommandError(f"--chunks {args.chunks}: a chunk needs at least 8 samples per side")
        path = save_zarr(volume, args.output, overwrite=args.force, chunks=args.chunks, compressor=args.compressor,
                         levels=args.levels, zarr_format=args.zarr_format)
    else:
        path = save_volume(volume, args.output, overwrite=args.force)
    if getattr(args, "json", False):
        from .common import print_json

        print_json({"output": str(path), **volume.describe(), **({"cut": cut} if cut else {})})
        return 0
    print(f"Wrote {path} ({' x '.join(map(str, volume.dimensions))} voxels, LPS geometry kept"
          + (f", cut by {len(tools)} tool(s)" if tools else "") + ")")
    return 0
