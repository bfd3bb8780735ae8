"""Surface extraction and mesh export, headless: what ``voxelscope mesh`` and the workbench's Export do.

Meshes are extracted in the volume frame and moved to patient coordinates on export, in LPS (DICOM, ITK, 3D
Slicer's files since version 4.11) or RAS (NIfTI, FreeSurfer, most 3D printing software), millimetres. An export
cannot lie:

- an isovalue outside the data's range, or one that gives no surface, is a one-line :class:`EmptySurfaceError`
  before anything is written;
- a surface of more than :data:`MAX_TRIANGLES` triangles is a :class:`MeshTooLargeError` unless the caller allows
  it (``--force`` on the command line; the window asks first), estimated before it is extracted where the method
  can count (:meth:`app.modes.surfaces.SurfaceMode.estimate`);
- decimation keeps a closed surface closed or is refused (:func:`app.mesh_cleanup.decimate`), and the sidecar
  gives ``volume_mm3`` only for watertight, outward meshes;
- files are written atomically with their JSON sidecar (both or neither, :mod:`app.mesh_files`), a full disk is
  an error naming the file, and an existing file is never replaced unless ``overwrite`` is set.

The work is in two steps so a caller can let go of the volume's samples between them (the command line does, to
keep the peak memory of a large export low): :func:`surface_for_export` extracts and places the surface,
:func:`write_export` cleans it up, validates and writes it, each reporting progress and honouring cancellation.
:func:`export_mesh` does both.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.common.vtk_bridge import run_algorithm, vtk_matrix
from algorithms.compare import triangulated

from . import __version__, mesh_cleanup
from .mesh_cleanup import Cleanup
from .mesh_files import MESH_SUFFIXES, check_mesh_targets, sidecar_path, write_mesh_files
from .modes import get_mode, mode_names
from .pipeline.lit_surfaces import SurfaceResult, polydata_stats
from .volume import Volume

__all__ = [
    "COORDINATE_SYSTEMS", "EmptySurfaceError", "MAX_TRIANGLES", "MESH_SUFFIXES", "MeshExport", "MeshTooLargeError",
    "SurfaceForExport", "check_isovalue", "closed_at_edges", "estimate_triangles", "export_mesh",
    "extract_surface", "merge_duplicate_points", "mesh_provenance", "sidecar_path", "surface_for_export",
    "surface_methods", "to_world", "write_export", "write_mesh",
]

COORDINATE_SYSTEMS = ("LPS", "RAS")
#: Largest mesh exported without asking: clean-up, validation and writing of larger ones take minutes and GiB.
MAX_TRIANGLES = 20_000_000


class EmptySurfaceError(ValueError):
    """The isovalue lies outside the data's range, or gives no surface (nothing to export or draw)."""


class MeshTooLargeError(ValueError):
    """The surface would have more than ``limit`` triangles. The command line needs ``--force``; the window asks the
    user and runs the export again with ``allow_large=True``. ``triangles`` is the (estimated) count."""

    def __init__(self, message: str, triangles: int, limit: int) -> None:
        super().__init__(message)
        self.triangles = int(triangles)
        self.limit = int(limit)


def source_name(volume) -> str:
    """How errors name a volume: its file's name, else "the volume"."""
    path = getattr(volume, "metadata", {}).get("source_path", "")
    return Path(path).name if path else "the volume"


def check_isovalue(volume: Volume, iso: float, name: str | None = None, *, closed: bool = False) -> None:
    """Refuse an isovalue that cannot give a surface: inside is ``value >= iso``, so a surface needs
    ``minimum < iso <= maximum`` (``closed``: capped at the volume's edge, :func:`closed_at_edges`, where only
    ``iso <= maximum`` is needed). An :class:`EmptySurfaceError` names the volume, its range and its units."""
    name = name or source_name(volume)
    units = volume.units_label
    if not np.isfinite(iso):
        raise EmptySurfaceError(f"{name}: the isovalue must be a finite number, got {iso}")
    lo, hi = volume.value_range
    if not (lo < iso or closed) or not iso <= hi:
        side = "above the largest value" if iso > hi else "at or below the smallest value"
        raise EmptySurfaceError(f"{name}: no surface at {iso:g} {units}, which is {side} (the values run from {lo:g} "
                                f"to {hi:g} {units}); choose an isovalue above {lo:g} and at most {hi:g} {units}")


def extract_surface(volume, method: str, iso: float, *, stride: int = 1, options: dict[str, Any] | None = None,
                    progress: ProgressCallback = None) -> SurfaceResult:
    """Run a registered surface mode (``voxelscope mesh --method``) on a volume (or scene item) at ``iso``.

    The surface is in the volume frame; ``stride`` > 1 uses the mode's coarse path.
    """
    return _surface_mode(method).extract(volume, float(iso), stride=stride, options=options, progress=progress)


def _surface_mode(method: str):
    mode = get_mode(method)
    if mode.output != "surface" or mode.input != "volume":
        raise ValueError(f"{method!r} does not extract surfaces from volumes; choose one of "
                         f"{', '.join(surface_methods())}")
    return mode


def surface_methods() -> list[str]:
    """The registered modes that extract a surface from a volume (``voxelscope mesh --method``)."""
    return mode_names(input="volume", output="surface")


def estimate_triangles(volume: Volume, method: str, iso: float, *, stride: int = 1,
                       progress: ProgressCallback = None) -> int | None:
    """The number of triangles ``method`` will make, counted without extracting (None if the method cannot say)."""
    return _surface_mode(method).estimate_triangles(volume, float(iso), stride=stride, progress=progress)


def closed_at_edges(volume: Volume, iso: float) -> Volume:
    """``volume`` padded by one voxel of a value below ``iso``, so that surfaces cut by the volume's edge close.

    A skull that leaves the scanned region (the neck at the last slice, for example) then gets a cap within one voxel
    outside the data instead of an open rim. The pad is the volume's minimum when that is below ``iso`` (air in CT),
    else a value just below ``iso``.
    """
    low = float(volume.value_range[0])
    pad = low if low < iso else iso - max(1.0, abs(iso) * 1e-3)
    return volume.padded(pad)


def to_world(polydata, volume, coordinates: str = "LPS", *, progress: ProgressCallback = None):
    """A copy of a volume-frame surface in patient coordinates (``LPS`` or ``RAS`` mm), strips kept.

    ``volume`` is a :class:`~app.volume.Volume` or its 4x4 ``local_to_world`` matrix. The volume's direction is
    right-handed (readers guarantee it) and LPS->RAS is a rotation by 180 degrees about the superior axis, so
    triangle winding, and with it the outward orientation, is preserved.
    """
    from vtkmodules.vtkCommonTransforms import vtkTransform
    from vtkmodules.vtkFiltersGeneral import vtkTransformFilter

    coordinates = coordinates.upper()
    if coordinates not in COORDINATE_SYSTEMS:
        raise ValueError(f"coordinates must be LPS or RAS, got {coordinates!r}")
    matrix = np.asarray(volume.local_to_world if hasattr(volume, "local_to_world") else volume, dtype=np.float64)
    if coordinates == "RAS":
        matrix = np.diag([-1.0, -1.0, 1.0, 1.0]) @ matrix
    transform = vtkTransform()
    transform.SetMatrix(vtk_matrix(matrix))
    moved = vtkTransformFilter()
    moved.SetTransform(transform)
    moved.SetInputData(polydata)
    output = run_algorithm(moved, progress)
    result = output.NewInstance()
    result.ShallowCopy(output)
    return result


def merge_duplicate_points(polydata, *, progress: ProgressCallback = None):
    """One point per position (exact matches only): voxel-face surfaces store every face's corners apart, and flying
    edges makes a point per cut edge even where several meet on one sample; a connected mesh is what an STL or PLY
    user expects. Cells that merging reduces to fewer than three points are dropped; the others are kept."""
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData

    clean = vtkCleanPolyData()
    clean.SetInputData(polydata)
    clean.PointMergingOn()
    clean.SetTolerance(0.0)
    clean.ConvertPolysToLinesOff()
    clean.ConvertLinesToPointsOff()
    clean.ConvertStripsToPolysOff()
    output = run_algorithm(clean, progress)
    result = output.NewInstance()
    result.ShallowCopy(output)
    return result


def write_mesh(polydata, path, *, overwrite: bool = False, sidecar: dict[str, Any] | None = None,
               progress: ProgressCallback = None) -> list[Path]:
    """Write a world-coordinate surface by extension (binary STL, binary PLY, OBJ, VTP) and, with ``sidecar``,
    ``<path>.json``, atomically and together (see :func:`app.mesh_files.write_mesh_files`). STL, PLY and OBJ get
    triangles. Returns the paths written."""
    if Path(path).suffix.lower() != ".vtp":
        polydata = triangulated(polydata)
    return write_mesh_files(polydata, path, sidecar=sidecar, overwrite=overwrite, progress=progress)


@dataclass
class SurfaceForExport:
    """A surface ready for :func:`write_export`: in patient coordinates, with what the sidecar records about where
    it came from. It holds no samples of the volume."""

    polydata: Any  # vtkPolyData, LPS or RAS mm
    stats: dict[str, Any]  # of the extracted representation (before merging and triangulation)
    source: dict[str, Any]  # file, format, series, modality, value units of the volume
    method: str
    iso: float
    coordinates: str
    parameters: dict[str, Any] = field(default_factory=dict)


@dataclass
class MeshExport:
    """Everything one export produced: files, counts, timing, validity and provenance."""

    paths: list[Path]
    stats: dict[str, Any]  # of the extracted representation (before clean-up, merging and triangulation)
    written: dict[str, Any]  # points, triangles, cells, strips of the file written
    validity: dict[str, Any] | None
    sidecar: dict[str, Any]


def _source_info(volume: Volume) -> dict[str, Any]:
    return {
        "source_file": volume.metadata.get("source_path", ""),
        "source_format": volume.metadata.get("source_format", ""),
        "series_uid": volume.metadata.get("series_uid", ""),
        "modality": volume.modality,
        "value_units": volume.units_label,
    }


def mesh_provenance(source, *, method: str, iso: float, coordinates: str, parameters: dict[str, Any],
                    stats: dict[str, Any], validity: dict[str, Any] | None) -> dict[str, Any]:
    """The sidecar content: source, series, method, parameters, coordinate system, units and counts. ``source`` is a
    :class:`~app.volume.Volume` or the dict :class:`SurfaceForExport` keeps of it."""
    source = _source_info(source) if isinstance(source, Volume) else source
    return {
        "software": f"Voxelscope {__version__}",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        **{key: source[key] for key in ("source_file", "source_format", "series_uid", "modality")},
        "value_units": source["value_units"],
        "iso_value": iso,
        "method": method,
        "parameters": parameters,
        "coordinate_system": coordinates,
        "length_units": "mm",
        "counts": {k: stats[k] for k in ("points", "triangles", "cells", "strips") if k in stats},
        "validity": validity,
    }


def _count_text(count: int) -> str:
    return f"{count / 1e6:.1f} M" if count >= 1_000_000 else f"{count:,}"


def _too_large(name: str, iso: float, units: str, triangles: int, limit: int, estimated: bool) -> MeshTooLargeError:
    what = "would have about" if estimated else "has"
    return MeshTooLargeError(
        f"{name}: the surface at {iso:g} {units} {what} {_count_text(triangles)} triangles, more than the "
        f"{_count_text(limit)} an export makes without asking (clean-up, validation and writing would take minutes "
        "and several GiB); choose another isovalue, use --stride 2, or add --force to export it anyway",
        triangles, limit)


def _triangle_count(polydata) -> int:
    return int(polydata_stats(polydata)["triangles"])


def surface_for_export(volume: Volume, *, method: str, iso: float, stride: int = 1,
                       options: dict[str, Any] | None = None, coordinates: str = "LPS", close_edges: bool = False,
                       allow_large: bool = False, max_triangles: int | None = None,
                       result: SurfaceResult | None = None, progress: ProgressCallback = None) -> SurfaceForExport:
    """Check the isovalue, extract the surface (unless ``result`` is given), and move it to patient coordinates.

    ``close_edges`` extracts from :func:`closed_at_edges` (so it cannot reuse a ``result``): surfaces cut by the
    volume's edge get a cap there. Coincident points are merged (voxel-face and flying-edges surfaces become
    connected) and cells that merging collapses are dropped.

    Raises
    ------
    EmptySurfaceError
        The isovalue is outside ``minimum < iso <= maximum`` of the data, or the surface has no triangles.
    MeshTooLargeError
        The surface has (or, counted before extraction, would have) more than ``max_triangles`` (default
        :data:`MAX_TRIANGLES`) triangles and ``allow_large`` is not set.
    """
    name = source_name(volume)
    units = volume.units_label
    max_triangles = MAX_TRIANGLES if max_triangles is None else int(max_triangles)
    coordinates = coordinates.upper()
    if coordinates not in COORDINATE_SYSTEMS:
        raise ValueError(f"coordinates must be LPS or RAS, got {coordinates!r}")
    check_isovalue(volume, iso, name, closed=close_edges)
    mode = _surface_mode(method)
    if close_edges and result is not None:
        raise ValueError("close_edges extracts the surface again from the padded volume; do not pass a result")
    frame = volume.local_to_world  # the padded volume's own frame with close_edges (one voxel further out)
    if result is None:
        source = closed_at_edges(volume, iso) if close_edges else volume
        frame = source.local_to_world
        if not allow_large:
            estimate = mode.estimate_triangles(source, float(iso), stride=stride, limit=max_triangles,
                                               progress=scaled(progress, 0.0, 0.1))
            if estimate is not None and estimate > max_triangles:
                raise _too_large(name, iso, units, estimate, max_triangles, estimated=True)
        result = mode.extract(source, float(iso), stride=stride, options=options, progress=scaled(progress, 0.1, 0.7))
        del source
    triangles = int(result.stats.get("triangles", _triangle_count(result.polydata)))
    if triangles > max_triangles and not allow_large:
        raise _too_large(name, iso, units, triangles, max_triangles, estimated=False)
    if triangles == 0:
        lo, hi = volume.value_range
        raise EmptySurfaceError(f"{name}: no surface at {iso:g} {units} (the values run from {lo:g} to {hi:g} "
                                f"{units}); choose an isovalue inside that range")
    world = to_world(result.polydata, frame, coordinates, progress=scaled(progress, 0.7, 0.8))
    if not mode.unique_points:
        world = merge_duplicate_points(world, progress=scaled(progress, 0.8, 1.0))
    if _triangle_count(world) == 0:
        raise EmptySurfaceError(f"{name}: the surface at {iso:g} {units} has no area: only single samples reach "
                                f"{iso:g} {units}; choose a lower isovalue")
    report(progress, 1.0)
    parameters = {"stride": stride, **(options or {}), "close_edges": bool(close_edges)}
    return SurfaceForExport(world, dict(result.stats), _source_info(volume), method, float(iso), coordinates,
                            parameters)


def write_export(surface: SurfaceForExport, path, *, cleanup: Cleanup | None = None, overwrite: bool = False,
                 sidecar: bool = True, progress: ProgressCallback = None) -> MeshExport:
    """Clean up (the steps of a :class:`app.mesh_cleanup.Cleanup`), validate and write a surface with its sidecar
    (``sidecar=False``: the mesh alone). STL, PLY and OBJ get triangles. Every step reports progress and honours
    cancellation.
    """
    path = check_mesh_targets(path, sidecar=sidecar, overwrite=overwrite)
    cleanup = (cleanup or Cleanup()).chosen()
    notes: dict[str, Any] = {}
    polydata = mesh_cleanup.apply(surface.polydata, progress=scaled(progress, 0.0, 0.4), notes=notes, **cleanup)
    triangles = triangulated(polydata)
    written = polydata if path.suffix.lower() == ".vtp" else triangles
    validity = mesh_cleanup.validity_report(triangles, progress=scaled(progress, 0.4, 0.8)).as_dict()
    del triangles
    written_stats = {k: v for k, v in polydata_stats(written).items() if k != "bytes"}
    provenance = mesh_provenance(surface.source, method=surface.method, iso=surface.iso,
                                 coordinates=surface.coordinates, parameters={**surface.parameters, **cleanup, **notes},
                                 stats=written_stats, validity=validity)
    paths = write_mesh_files(written, path, overwrite=overwrite, sidecar=provenance if sidecar else None,
                             progress=scaled(progress, 0.8, 1.0))
    report(progress, 1.0)
    return MeshExport(paths, dict(surface.stats), written_stats, validity, provenance)


def export_mesh(volume: Volume, path, *, method: str, iso: float, stride: int = 1,
                options: dict[str, Any] | None = None, coordinates: str = "LPS",
                cleanup: Cleanup | None = None, close_edges: bool = False, overwrite: bool = False,
                allow_large: bool = False, progress: ProgressCallback = None, result: SurfaceResult | None = None,
                sidecar: bool = True) -> MeshExport:
    """Extract (unless ``result`` is given), clean up, validate and write a mesh with its sidecar.

    The targets are checked first (format, existing files, folder), then :func:`surface_for_export` and
    :func:`write_export` run (see them for ``close_edges``, ``allow_large``, ``cleanup`` and the errors).
    ``MeshExport.stats`` describes the extracted representation, ``MeshExport.written`` the file.
    ``sidecar=False`` writes no ``<file>.json`` (one-mesh-per-label exports list every mesh in one file instead).
    """
    path = check_mesh_targets(path, sidecar=sidecar, overwrite=overwrite)
    surface = surface_for_export(volume, method=method, iso=iso, stride=stride, options=options,
                                 coordinates=coordinates, close_edges=close_edges, allow_large=allow_large,
                                 result=result, progress=scaled(progress, 0.0, 0.5))
    return write_export(surface, path, cleanup=cleanup, overwrite=overwrite, sidecar=sidecar,
                        progress=scaled(progress, 0.5, 1.0))
