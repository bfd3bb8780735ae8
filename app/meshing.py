"""Surface extraction and mesh export, headless: what ``voxelscope mesh`` and the workbench's Export do.

Meshes are extracted in the volume frame and moved to patient coordinates on export, in LPS (DICOM, ITK, 3D
Slicer's files since version 4.11) or RAS (NIfTI, FreeSurfer, most 3D printing software), millimetres. Files are
written atomically (temporary file + rename) and an existing file is never replaced unless ``overwrite`` is set.
Every export writes a JSON sidecar (``<mesh file>.json``) recording where the mesh came from.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.progress import ProgressCallback, scaled

from algorithms.compare import triangulated

from .io.atomic import atomic_output
from .io.errors import FileExistsRefusal, VolumeWriteError
from .pipeline.surfaces import SurfaceResult, polydata_stats
from .volume import Volume

MESH_SUFFIXES = (".stl", ".ply", ".obj", ".vtp")
COORDINATE_SYSTEMS = ("LPS", "RAS")


def default_iso(volume: Volume) -> float:
    """A sensible first isovalue: 300 HU (bone) for CT in HU, else 35 % into the robust value range."""
    if volume.units == "HU":
        return 300.0
    lo, hi = volume.percentile_range()
    return lo + 0.35 * (hi - lo)


def extract_surface(volume, method: str, iso: float, *, stride: int = 1, options: dict[str, Any] | None = None,
                    progress: ProgressCallback = None) -> SurfaceResult:
    """Run a registered surface mode (``voxelscope mesh --method``) on a volume (or scene item) at ``iso``.

    The surface is in the volume frame; ``stride`` > 1 uses the mode's coarse path.
    """
    from .modes import get_mode

    mode = get_mode(method)
    if mode.output != "surface" or mode.input != "volume":
        raise ValueError(f"{method!r} does not extract surfaces from volumes; choose one of "
                         f"{', '.join(surface_methods())}")
    return mode.extract(volume, float(iso), stride=stride, options=options, progress=progress)


def surface_methods() -> list[str]:
    """The registered modes that extract a surface from a volume (``voxelscope mesh --method``)."""
    from .modes import mode_names

    return mode_names(input="volume", output="surface")


def closed_at_edges(volume: Volume, iso: float) -> Volume:
    """``volume`` padded by one voxel of a value below ``iso``, so that surfaces cut by the volume's edge close.

    A skull that leaves the scanned region (the neck at the last slice, for example) then gets a cap within one voxel
    outside the data instead of an open rim. The pad is the volume's minimum when that is below ``iso`` (air in CT),
    else a value just below ``iso``.
    """
    low = float(volume.array.min())
    pad = low if low < iso else iso - max(1.0, abs(iso) * 1e-3)
    return volume.padded(pad)


def to_world(polydata, volume: Volume, coordinates: str = "LPS"):
    """A copy of a volume-frame surface in patient coordinates (``LPS`` or ``RAS`` mm), strips kept.

    The volume's direction is right-handed (readers guarantee it) and LPS->RAS is a rotation by 180 degrees about
    the superior axis, so triangle winding, and with it the outward orientation, is preserved.
    """
    from vtkmodules.vtkCommonTransforms import vtkTransform
    from vtkmodules.vtkFiltersGeneral import vtkTransformFilter

    from algorithms.common.vtk_bridge import run_algorithm, vtk_matrix

    coordinates = coordinates.upper()
    if coordinates not in COORDINATE_SYSTEMS:
        raise ValueError(f"coordinates must be LPS or RAS, got {coordinates!r}")
    matrix = volume.local_to_world
    if coordinates == "RAS":
        matrix = np.diag([-1.0, -1.0, 1.0, 1.0]) @ matrix
    transform = vtkTransform()
    transform.SetMatrix(vtk_matrix(matrix))
    moved = vtkTransformFilter()
    moved.SetTransform(transform)
    moved.SetInputData(polydata)
    output = run_algorithm(moved)
    result = output.NewInstance()
    result.ShallowCopy(output)
    return result


def merge_duplicate_points(polydata):
    """One point per position (exact matches only): voxel-face surfaces store every face's corners apart; a
    connected mesh is what an STL or PLY user expects. Cells, degenerate ones included, are kept as they are."""
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData

    from algorithms.common.vtk_bridge import run_algorithm

    clean = vtkCleanPolyData()
    clean.SetInputData(polydata)
    clean.PointMergingOn()
    clean.SetTolerance(0.0)
    clean.ConvertPolysToLinesOff()
    clean.ConvertLinesToPointsOff()
    clean.ConvertStripsToPolysOff()
    output = run_algorithm(clean)
    result = output.NewInstance()
    result.ShallowCopy(output)
    return result


def sidecar_path(mesh_path) -> Path:
    mesh_path = Path(mesh_path)
    return mesh_path.with_name(mesh_path.name + ".json")


def write_mesh(polydata, path, *, overwrite: bool = False, sidecar: dict[str, Any] | None = None) -> list[Path]:
    """Write a world-coordinate surface by extension (binary STL, binary PLY, OBJ, VTP), atomically.

    With ``sidecar``, also writes ``<path>.json`` holding it. Neither file replaces an existing one unless
    ``overwrite``; both are checked before anything is written. Returns the paths written.
    """
    from vtkmodules.vtkIOGeometry import vtkOBJWriter, vtkSTLWriter
    from vtkmodules.vtkIOPLY import vtkPLYWriter
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    path = Path(path).expanduser()
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise VolumeWriteError(f"{path}: unknown mesh format '{suffix}'; use one of {', '.join(MESH_SUFFIXES)}")
    side = sidecar_path(path) if sidecar is not None else None
    if not overwrite:
        for target in (path, side):
            if target is not None and target.exists():
                raise FileExistsRefusal(target)
    if suffix == ".vtp":
        writer = vtkXMLPolyDataWriter()
        writer.SetCompressorTypeToZLib()
        data = polydata
    else:
        data = triangulated(polydata)
        if suffix == ".stl":
            writer = vtkSTLWriter()
            writer.SetFileTypeToBinary()
        elif suffix == ".ply":
            writer = vtkPLYWriter()
            writer.SetFileTypeToBinary()
        else:
            writer = vtkOBJWriter()
    writer.SetInputData(data)
    written = []
    with atomic_output(path, overwrite=overwrite) as temporary:
        writer.SetFileName(str(temporary))
        if writer.Write() != 1:
            raise VolumeWriteError(f"{path}: VTK could not write the mesh")
    written.append(path)
    if side is not None:
        with atomic_output(side, overwrite=overwrite) as temporary:
            temporary.write_text(json.dumps(sidecar, indent=2, default=_json_default) + "\n")
        written.append(side)
    return written


def _json_default(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot serialise {type(value).__name__}")


@dataclass
class MeshExport:
    """Everything one export produced: files, counts, timing, validity and provenance."""

    paths: list[Path]
    stats: dict[str, Any]  # of the extracted representation (before clean-up, merging and triangulation)
    written: dict[str, Any]  # points, triangles, cells, strips of the file written
    validity: dict[str, Any] | None
    sidecar: dict[str, Any]


def mesh_provenance(volume: Volume, *, method: str, iso: float, coordinates: str, parameters: dict[str, Any],
                    stats: dict[str, Any], validity: dict[str, Any] | None) -> dict[str, Any]:
    """The sidecar content: source, series, method, parameters, coordinate system, units and counts."""
    from . import __version__

    return {
        "software": f"Voxelscope {__version__}",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "source_file": volume.metadata.get("source_path", ""),
        "source_format": volume.metadata.get("source_format", ""),
        "series_uid": volume.metadata.get("series_uid", ""),
        "modality": volume.modality,
        "value_units": volume.units_label,
        "iso_value": iso,
        "method": method,
        "parameters": parameters,
        "coordinate_system": coordinates,
        "length_units": "mm",
        "counts": {k: stats[k] for k in ("points", "triangles", "cells", "strips") if k in stats},
        "validity": validity,
    }


def export_mesh(volume: Volume, path, *, method: str, iso: float, stride: int = 1,
                options: dict[str, Any] | None = None, coordinates: str = "LPS",
                cleanup: dict[str, Any] | None = None, close_edges: bool = False, overwrite: bool = False,
                progress: ProgressCallback = None, result: SurfaceResult | None = None) -> MeshExport:
    """Extract (unless ``result`` is given), clean up, validate and write a mesh with its sidecar.

    ``close_edges`` extracts from :func:`closed_at_edges` (so it cannot reuse a ``result``): surfaces cut by the
    volume's edge get a cap there.

    On the way out, coincident points are merged (voxel-face surfaces become connected) and triangles that merging
    collapses (zero area, where the isovalue equals sample values) are dropped; STL, PLY and OBJ get triangles.
    ``MeshExport.stats`` describes the extracted representation, ``MeshExport.written`` the file.

    ``cleanup`` keys (all optional): ``smooth_iterations`` (windowed sinc), ``smooth_passband``,
    ``decimate`` (target reduction in [0, 1)), ``largest_component`` (bool), ``fill_holes_mm`` (max hole size).
    """
    from . import mesh_cleanup

    path = Path(path).expanduser()
    if not overwrite:
        for target in (path, sidecar_path(path)):
            if target.exists():
                raise FileExistsRefusal(target)
    cleanup = dict(cleanup or {})
    if close_edges and result is not None:
        raise ValueError("close_edges extracts the surface again from the padded volume; do not pass a result")
    if result is None:
        source = closed_at_edges(volume, iso) if close_edges else volume
        result = extract_surface(source, method, iso, stride=stride, options=options,
                                 progress=scaled(progress, 0.0, 0.6))
    polydata = result.polydata
    polydata = mesh_cleanup.apply(polydata, progress=scaled(progress, 0.6, 0.85), **cleanup)
    world = merge_duplicate_points(to_world(polydata, volume, coordinates))
    written = triangulated(world) if path.suffix.lower() != ".vtp" else world
    validity = mesh_cleanup.validity_report(triangulated(world)).as_dict()
    stats = dict(result.stats)
    written_stats = {k: v for k, v in polydata_stats(written).items() if k != "bytes"}
    parameters = {"stride": stride, **(options or {}), "close_edges": bool(close_edges), **cleanup}
    sidecar = mesh_provenance(volume, method=method, iso=iso, coordinates=coordinates.upper(), parameters=parameters,
                              stats=written_stats, validity=validity)
    paths = write_mesh(world, path, overwrite=overwrite, sidecar=sidecar)
    if progress is not None:
        progress(1.0)
    return MeshExport(paths, stats, written_stats, validity, sidecar)
