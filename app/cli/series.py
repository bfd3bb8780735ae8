"""``voxelscope series``: list the image series in a DICOM folder."""

from __future__ import annotations

from .common import print_json

NAME = "series"
HELP = "list the DICOM image series in a folder"
ORDER = 50


def add_arguments(parser) -> None:
    parser.add_argument("folder")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args) -> int:
    from ..io import list_series
    from ..samples import resolve_path

    series = list_series(resolve_path(args.folder))
    if args.json:
        print_json({"series": series})
        return 0
    if not series:
        print("No image series found")
    for item in series:
        print(f"{item['series_uid']}  {item['slices']:4d} images {item['columns']}x{item['rows']}  "
              f"{item['modality'] or '?':3s} {item['description']}")
    return 0
