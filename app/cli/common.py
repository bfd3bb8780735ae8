"""What the commands share: the input arguments and loading, mode-option flags built from the registry, JSON output."""

from __future__ import annotations

import argparse
import json
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterable

EXIT_ERROR = 1
EXIT_USAGE = 2


class CommandError(Exception):
    """An error whose message is shown to the user as it is."""


# --------------------------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------------------------
def add_input_arguments(parser: argparse.ArgumentParser, *, meshes: bool = False, name: str = "path") -> None:
    """The input path and the options for reading it (DICOM series choice, raw layout)."""
    what = "volume file, DICOM folder or mesh file (STL, OBJ, PLY, VTP, OFF)" if meshes else "volume file or DICOM folder"
    parser.add_argument(name, help=f"{what}; 'sample' for the bundled CT phantom, 'sample:mri' for the bundled brain "
                                   "MRI")
    parser.add_argument("--series", metavar="UID", help="DICOM SeriesInstanceUID to load (default: the largest stack)")
    parser.add_argument("--strict-spacing", action="store_true",
                        help="refuse DICOM series with missing slices or uneven spacing instead of resampling")
    parser.add_argument("--volume", type=int, metavar="N", dest="volume_index",
                        help="DICOM series with several volumes (time points, echoes, MOSAIC files): load volume N "
                             "(0 is the first; 'info' lists them)")
    parser.add_argument("--allow-gaps", action="store_true",
                        help="fill large gaps in a DICOM series by interpolation (refused by default; the invented "
                             "slices are reported)")
    raw = parser.add_argument_group("raw files (no header)")
    raw.add_argument("--raw-dims", nargs=3, type=int, metavar=("NX", "NY", "NZ"), help="voxels along x, y, z")
    raw.add_argument("--raw-dtype", default="uint8", help="voxel type, e.g. uint8, int16, float32 (default uint8)")
    raw.add_argument("--raw-spacing", nargs=3, type=float, default=(1.0, 1.0, 1.0), metavar=("SX", "SY", "SZ"),
                     help="voxel size in mm (default 1 1 1)")
    raw.add_argument("--raw-endian", choices=("little", "big"), default="little")
    raw.add_argument("--raw-header", type=int, default=0, metavar="BYTES", help="bytes to skip at the start")


def load_volume_argument(args, path: str | None = None):
    """The volume named on the command line (``sample`` and ``sample:NAME`` resolved), as a :class:`Volume`."""
    from ..io import RawLayout, load_volume
    from ..samples import resolve_path

    location = resolve_path(path if path is not None else args.path)
    raw = None
    if getattr(args, "raw_dims", None):
        raw = RawLayout(tuple(args.raw_dims), args.raw_dtype, tuple(args.raw_spacing), byte_order=args.raw_endian,
                        header_bytes=args.raw_header)
    keywords: dict[str, Any] = {"series_uid": getattr(args, "series", None), "raw": raw,
                                "irregular": "error" if getattr(args, "strict_spacing", False) else "resample"}
    if getattr(args, "allow_gaps", False):
        keywords["allow_gaps"] = True
    if getattr(args, "volume_index", None) is not None:
        keywords["volume_index"] = args.volume_index
    return load_volume(location, **keywords)


def load_item(args, path: str | None = None):
    """The scene item named on the command line: a volume item, or a mesh item for mesh files."""
    from ..io.meshes import is_mesh_path, load_mesh
    from ..samples import resolve_path
    from ..scene import MeshItem, VolumeItem

    text = path if path is not None else args.path
    location = resolve_path(text)
    if is_mesh_path(location):
        return MeshItem.from_mesh(load_mesh(location), _item_name(location))
    volume = load_volume_argument(args, text)
    return VolumeItem(_item_name(location), volume=volume, metadata=dict(volume.metadata))


def _item_name(path: Path) -> str:
    name = Path(path).name
    for suffix in (".gz", ".nii", ".nrrd", ".nhdr", ".mha", ".mhd", ".vti", ".vtk", ".stl", ".obj", ".ply", ".vtp",
                   ".off", ".dcm"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
    return name or str(path)


def add_cut_arguments(parser: argparse.ArgumentParser) -> None:
    """``--cut SPEC`` (repeatable), ``--cut-mode``, ``--cut-eval``: cut-away tools in LPS mm (source 002, 2.5)."""
    group = parser.add_argument_group("cut-away tools (LPS mm, angles in degrees about x, then y, then z)")
    group.add_argument("--cut", action="append", default=[], metavar="SPEC",
                       help="a tool, repeatable (several tools remove the union of their removals): sphere:X,Y,Z,R | "
                            "box:X,Y,Z,SX,SY,SZ[,RX,RY,RZ] (centre, full sizes) | cylinder:X,Y,Z,R,H[,RX,RY,RZ] | "
                            "plane:X,Y,Z,NX,NY,NZ (removes the side the normal points into) | "
                            "mask:FILE[@TRANSFORM.json] (a mask or distance field on its own grid)")
    group.add_argument("--cut-mode", default="remove", choices=("remove", "keep"),
                       help="remove what is inside the tools (default), or keep only the inside (a region of interest)")
    group.add_argument("--cut-eval", default="binary", choices=("binary", "distance"),
                       help="binary test per sample (default), or the difference of distance fields: a smooth cut "
                            "surface with the tool's normals")


def tools_from_args(args) -> list:
    """The tools of ``--cut`` (a CommandError with the problem for a bad specification)."""
    from ..cutaways import tools_from_specs

    try:
        return tools_from_specs(getattr(args, "cut", None) or [], mode=getattr(args, "cut_mode", "remove"))
    except ValueError as exc:
        raise CommandError(str(exc)) from None


def like_item(args):
    """The ``--like`` volume as a scene item (None without ``--like``)."""
    from ..io.meshes import is_mesh_path
    from ..samples import resolve_path
    from ..scene import VolumeItem

    if not getattr(args, "like", None):
        return None
    path = resolve_path(args.like)
    if is_mesh_path(path):
        raise CommandError(f"{args.like}: --like takes a volume (its grid is copied), not a mesh")
    return VolumeItem(path.name, volume=load_volume_argument(args, args.like))


def mesh_item(text: str, command: str):
    """The mesh argument of ``command`` as a scene item; a one-line error when it names no mesh file."""
    from ..io.meshes import is_mesh_path, load_mesh
    from ..samples import resolve_path
    from ..scene import MeshItem

    path = resolve_path(text)
    if not is_mesh_path(path):
        raise CommandError(f"{text}: not a mesh file (STL, OBJ, PLY, VTP or OFF, optionally .gz); {command} takes a "
                           "surface mesh")
    return MeshItem.from_mesh(load_mesh(path))


def field_output(args, what: str) -> Path:
    """``args.output`` checked as a new (or ``--force``) volume file; ``what`` names the content in the error."""
    from ..io import WRITABLE_SUFFIXES

    output = refuse_existing(args.output, args.force)
    if not str(output).lower().endswith(WRITABLE_SUFFIXES):
        raise CommandError(f"{output}: {what} is written as {', '.join(WRITABLE_SUFFIXES)}; choose one of these "
                           "extensions")
    return output


@contextmanager
def terminal_progress(name: str, *, quiet: bool = False):
    """A progress callback (fractions 0 to 1) that prints ``name: NN %`` on standard error when it is a terminal;
    None when ``quiet`` (``--json``) or when standard error is a pipe or a file (scripts and tests get one-line
    errors only). The line ends with the block."""
    if quiet or not sys.stderr.isatty():
        yield None
        return
    shown = [-1]

    def show(fraction: float) -> None:
        percent = int(100 * fraction)
        if percent != shown[0]:
            shown[0] = percent
            print(f"\r{name}: {percent:3d} %", end="", file=sys.stderr, flush=True)

    try:
        yield show
    finally:
        if shown[0] >= 0:
            print(file=sys.stderr)


# --------------------------------------------------------------------------------------------------------------
# The grid a field is made on (voxelise, distance, csg)
# --------------------------------------------------------------------------------------------------------------
def add_grid_arguments(parser: argparse.ArgumentParser, *, padding: int, required: bool = True) -> None:
    """``--grid N | --like VOLUME | --spacing SX SY SZ`` and ``--padding``: where a field is sampled."""
    from ..operations.voxelise import DEFAULT_GRID

    where = parser.add_mutually_exclusive_group(required=required)
    where.add_argument("--grid", type=int, metavar="N",
                       help=f"N voxels along the mesh's longest side, cubic voxels (e.g. {DEFAULT_GRID})")
    where.add_argument("--like", metavar="VOLUME",
                       help="use exactly this volume's grid: dimensions, spacing, origin and direction ('sample' "
                            "for the bundled CT)")
    where.add_argument("--spacing", nargs=3, type=float, metavar=("SX", "SY", "SZ"), help="voxel size in mm")
    parser.add_argument("--padding", type=int, default=padding, metavar="VOXELS",
                        help=f"voxels of margin around the mesh's bounding box with --grid or --spacing (default "
                             f"{padding})")


def grid_from_args(args) -> dict[str, Any]:
    """The grid flags as the operations' options (``--like`` travels as an item: :func:`like_item`)."""
    return {"grid": args.grid, "padding": args.padding,
            "spacing": " ".join(map(repr, args.spacing)) if args.spacing else None}


# --------------------------------------------------------------------------------------------------------------
# Mesh clean-up
# --------------------------------------------------------------------------------------------------------------
def add_cleanup_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of :class:`app.mesh_cleanup.Cleanup`."""
    parser.add_argument("--smooth", type=int, default=0, metavar="ITERATIONS",
                        help="windowed-sinc smoothing iterations")
    parser.add_argument("--passband", type=float, default=0.1, help="smoothing pass band in (0, 2] (default 0.1)")
    parser.add_argument("--decimate", type=float, default=0.0, metavar="FRACTION",
                        help="quadric decimation: fraction of triangles to remove, in [0, 1)")
    parser.add_argument("--largest", action="store_true", help="keep the largest connected component only")
    parser.add_argument("--fill-holes", type=float, default=0.0, metavar="MM", help="close holes up to this size (mm)")


def cleanup_from_args(args):
    """The :class:`app.mesh_cleanup.Cleanup` the flags ask for (a CommandError names a value out of range)."""
    from ..mesh_cleanup import Cleanup

    try:
        return Cleanup(smooth_iterations=args.smooth, smooth_passband=args.passband, decimate=args.decimate,
                       largest_component=args.largest, fill_holes_mm=args.fill_holes)
    except ValueError as exc:
        raise CommandError(str(exc)) from None


def run_operation(name: str, items: dict, options: dict, args):
    """Run the operation ``name`` (:mod:`app.operations`) on ``items`` with ``options`` already resolved, showing
    progress on a terminal; its warnings go to standard error, one line each. Returns the result."""
    from ..operations import get_operation

    with terminal_progress(name, quiet=args.json) as progress:
        result = get_operation(name).run(items, options, progress=progress)
    for warning in result.report.get("warnings", []):
        print(f"voxelscope: warning: {warning}", file=sys.stderr)
    return result


def refuse_existing(path, force: bool) -> Path:
    """``path`` as a Path; a CommandError if it exists and ``force`` is not set."""
    path = Path(path).expanduser()
    if path.exists() and not force:
        raise CommandError(f"{path} already exists; choose another name or add --force")
    return path


def print_json(data: dict[str, Any]) -> None:
    print(json.dumps(data, indent=2, default=_json_default))


def _json_default(value):
    from ..io.atomic import numpy_json

    try:
        return numpy_json(value)
    except TypeError:
        return str(value)


# --------------------------------------------------------------------------------------------------------------
# Mode options as flags
# --------------------------------------------------------------------------------------------------------------
OPTION_PREFIX = "mode_option_"


def add_mode_option_flags(parser: argparse.ArgumentParser, modes: Iterable) -> None:
    """One flag per option of the given modes (``--light-samples N``...), values checked by the chosen mode."""
    group = parser.add_argument_group("mode options (see 'voxelscope modes'; each applies to the modes that "
                                      "declare it)")
    seen: dict[str, list[str]] = {}
    options = {}
    for mode in modes:
        for option in mode.options:
            seen.setdefault(option.name, []).append(mode.name)
            options.setdefault(option.name, option)
    for name, option in options.items():
        users = ", ".join(seen[name])
        details = [option.help]
        if option.choices is not None:
            details.append("choices: " + ", ".join(map(str, option.allowed)))
        if option.default is not None:
            details.append(f"default {option.default}{' ' + option.unit if option.unit else ''}")
        details.append(f"modes: {users}")
        help_text = "; ".join(details).replace("%", "%%")
        metavar = option.unit.upper() if option.unit else option.type.upper()
        try:
            if option.type == "bool":
                group.add_argument(option.flag, dest=OPTION_PREFIX + name, action=argparse.BooleanOptionalAction,
                                   default=None, help=help_text)
            else:
                group.add_argument(option.flag, dest=OPTION_PREFIX + name, default=None, metavar=metavar,
                                   help=help_text)
        except argparse.ArgumentError as exc:
            raise CommandError(f"mode option {option.flag} clashes with a flag of the command: {exc}") from None


def mode_options_from_args(args) -> dict[str, Any]:
    """The mode options given on the command line (as text; the mode validates and converts them)."""
    return {key[len(OPTION_PREFIX):]: value for key, value in vars(args).items()
            if key.startswith(OPTION_PREFIX) and value is not None}
