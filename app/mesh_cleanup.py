"""Clinician-ready post-processing of extracted surfaces, headless: smoothing, decimation, clean-up, validation.

Each step takes a triangle ``vtkPolyData`` (strips and polygons are triangulated first) in millimetres and returns
a new one, running VTK's filter through :func:`algorithms.common.vtk_bridge.run_algorithm`, so progress is forwarded
and VTK errors become exceptions. Steps that move points recompute point normals when the input had them (stale normals
would shade the old shape); winding is never changed except by :func:`fill_small_holes`, which makes the patches
agree with their surroundings.

- :func:`smooth`: windowed-sinc low-pass (Taubin et al.), no shrinkage; ``vtkWindowedSincPolyDataFilter``.
- :func:`decimate`: quadric error decimation (Garland & Heckbert 1997) preserving volume; ``vtkQuadricDecimation``.
  A closed surface stays closed: when quadric decimation opens it, topology-preserving decimation
  (``vtkDecimatePro``, no splitting, no boundary vertices removed) is used instead, and if that cannot keep it
  closed either, decimation is refused with a message.
- :func:`keep_largest_component`: drop islands (noise, loose fragments); ``vtkPolyDataConnectivityFilter``.
- :func:`fill_small_holes`: close holes up to a size, e.g. where a surface meets the edge of the scan;
  ``vtkFillHolesFilter``.
- :func:`validity_report`: watertight, manifold, outward, pieces, counts, area and volume (the definitions of
  :mod:`algorithms.compare`, computed lean and with progress by :mod:`app.mesh_validity`).
- :func:`apply`: the steps chosen for an export, in that order (largest piece, holes, smoothing, decimation).
- :class:`Cleanup`: the steps chosen for an export as one value, the one type the command line's flags, the export
  dialog and the one-mesh-per-label export fill in.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkPolyData

from algorithms import compare as surface_compare
from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.common.vtk_bridge import polydata_arrays, run_algorithm

from .mesh_validity import edge_report, validity_numbers

__all__ = [
    "Cleanup",
    "DecimationError",
    "ValidityReport",
    "apply",
    "decimate",
    "fill_small_holes",
    "keep_largest_component",
    "smooth",
    "validity_report",
]


def _checked_polydata(polydata) -> vtkPolyData:
    if not isinstance(polydata, vtkPolyData):
        raise ValueError(f"expected a vtkPolyData surface, got {type(polydata).__name__}")
    return surface_compare.triangulated(polydata)


def _detached(output: vtkPolyData) -> vtkPolyData:
    """A copy of a filter's output that no longer changes when the filter runs again."""
    result = vtkPolyData()
    result.ShallowCopy(output)
    return result


def _without_point_normals(polydata: vtkPolyData) -> vtkPolyData:
    """A shallow copy without its point normals: ``vtkPolyDataNormals`` passes existing normals through unchanged
    (VTK 9.7), so they must go before it can compute new ones."""
    result = _detached(polydata)
    point_data = result.GetPointData()
    normals = point_data.GetNormals()
    if normals is not None:
        index = next(i for i in range(point_data.GetNumberOfArrays()) if point_data.GetAbstractArray(i) is normals)
        point_data.RemoveArray(index)
    return result


def _with_point_normals(polydata: vtkPolyData, progress: ProgressCallback, *, consistent: bool = False) -> vtkPolyData:
    """Point normals recomputed from the triangles (no splitting, no automatic orientation). The winding is kept as
    it is, or with ``consistent`` turned where a triangle disagrees with its neighbours (``vtkPolyDataNormals``
    consistency, which starts from the surface's own triangles)."""
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals

    normals = vtkPolyDataNormals()
    normals.SetInputData(_without_point_normals(polydata))
    normals.ComputePointNormalsOn()
    normals.ComputeCellNormalsOff()
    normals.SplittingOff()
    normals.SetConsistency(consistent)
    normals.AutoOrientNormalsOff()
    return _detached(run_algorithm(normals, progress))


def _finish(result: vtkPolyData, had_normals: bool, progress: ProgressCallback) -> vtkPolyData:
    if had_normals:
        return _with_point_normals(result, progress)
    report(progress, 1.0)
    return result


def _has_normals(polydata: vtkPolyData) -> bool:
    return polydata.GetPointData().GetNormals() is not None


def smooth(polydata, iterations: int = 20, passband: float = 0.1, *, progress: ProgressCallback = None) -> vtkPolyData:
    """Windowed-sinc smoothing: removes the staircase of a voxel grid without shrinking the surface.

    Parameters
    ----------
    polydata : vtkPolyData
        Triangle surface (mm).
    iterations : int
        Degree of the polynomial approximating the filter (VTK's number of iterations), 1 or more; 10-30 is usual.
    passband : float
        Pass band in (0, 2]: smaller smooths more (0.1 is moderate, 0.01 strong). Coordinates are normalised to a
        unit cube first, so the value does not depend on the size of the surface.
    progress : callable, optional

    Notes
    -----
    Boundary and feature-edge smoothing are off, so open rims stay where they are and sharp edges are not
    treated differently. G. Taubin, T. Zhang, G. Golub, "Optimal surface smoothing as filter design", ECCV 1996.
    """
    from vtkmodules.vtkFiltersCore import vtkWindowedSincPolyDataFilter

    polydata = _checked_polydata(polydata)
    if isinstance(iterations, bool) or int(iterations) != iterations or iterations < 1:
        raise ValueError(f"iterations must be a whole number >= 1, got {iterations!r}")
    if not np.isfinite(passband) or not 0.0 < passband <= 2.0:
        raise ValueError(f"passband must be in (0, 2], got {passband!r}")
    smoother = vtkWindowedSincPolyDataFilter()
    smoother.SetInputData(polydata)
    smoother.SetNumberOfIterations(int(iterations))
    smoother.SetPassBand(float(passband))
    smoother.NormalizeCoordinatesOn()
    smoother.BoundarySmoothingOff()
    smoother.FeatureEdgeSmoothingOff()
    result = _detached(run_algorithm(smoother, scaled(progress, 0.0, 0.9)))
    return _finish(result, _has_normals(polydata), scaled(progress, 0.9, 1.0))


class DecimationError(ValueError):
    """Decimation would open a closed surface (both quadric and topology-preserving decimation were tried)."""


def decimate(polydata, target_reduction: float, *, progress: ProgressCallback = None,
             notes: dict[str, Any] | None = None) -> vtkPolyData:
    """Reduce the number of triangles by quadric error decimation, preserving the enclosed volume; a closed
    surface stays closed.

    Parameters
    ----------
    polydata : vtkPolyData
        Triangle surface (mm).
    target_reduction : float
        Fraction of triangles to remove, in [0, 1): 0.75 keeps about a quarter.
    progress : callable, optional
    notes : dict, optional
        Filled with ``decimation`` (the method used) and ``decimation_achieved`` (the fraction of triangles
        removed), for the sidecar.

    Raises
    ------
    DecimationError
        The surface is closed (watertight) and neither decimation keeps it closed.

    Notes
    -----
    Quadric decimation collapses edges without checking the link condition, so on a closed surface with thin
    parts (a skull's orbits, two voxels thick) it can make edges with one or three triangles. When the input is
    watertight and the output is not, the surface is decimated again by ``vtkDecimatePro`` with topology
    preserved, splitting off and boundary vertices kept (Schroeder, Zarge, Lorensen, "Decimation of triangle
    meshes", SIGGRAPH 1992), which may remove fewer triangles than asked; if even that opens it, the step is
    refused. M. Garland, P. S. Heckbert, "Surface simplification using quadric error metrics", SIGGRAPH 1997,
    doi:10.1145/258734.258849. Volume preservation as in Lindstrom & Turk 1998.
    """
    return _decimation(polydata, target_reduction, progress, notes if notes is not None else {})


def _watertight(polydata) -> bool:
    points, triangles = surface_compare.surface_arrays(polydata)
    return edge_report(points.shape[0], triangles)[0].watertight


def _decimation(polydata, target_reduction: float, progress: ProgressCallback, notes: dict) -> vtkPolyData:
    """:func:`decimate`'s body (also reached from :func:`apply`, whose ``decimate`` argument hides the name)."""
    from vtkmodules.vtkFiltersCore import vtkDecimatePro, vtkQuadricDecimation

    polydata = _checked_polydata(polydata)
    if not np.isfinite(target_reduction) or not 0.0 <= target_reduction < 1.0:
        raise ValueError(f"target_reduction is the fraction of triangles to remove, in [0, 1); got {target_reduction!r}")
    closed = _watertight(polydata)
    report(progress, 0.1)
    decimator = vtkQuadricDecimation()
    decimator.SetInputData(polydata)
    decimator.SetTargetReduction(float(target_reduction))
    decimator.VolumePreservationOn()
    result = _detached(run_algorithm(decimator, scaled(progress, 0.1, 0.5)))
    method = "quadric (vtkQuadricDecimation, volume preserving)"
    if closed and not _watertight(result):
        keeper = vtkDecimatePro()
        keeper.SetInputData(polydata)
        keeper.SetTargetReduction(float(target_reduction))
        keeper.PreserveTopologyOn()
        keeper.SplittingOff()
        keeper.BoundaryVertexDeletionOff()
        result = surface_compare.triangulated(_detached(run_algorithm(keeper, scaled(progress, 0.5, 0.85))))
        method = "topology-preserving (vtkDecimatePro): quadric decimation would have opened the closed surface"
        if not _watertight(result):
            raise DecimationError(
                f"decimating {100 * target_reduction:g} % of the triangles would open this closed surface (quadric "
                "and topology-preserving decimation both leave holes); export without decimation or with a smaller "
                "fraction")
    before = polydata.GetNumberOfCells()
    notes["decimation"] = method
    notes["decimation_achieved"] = round(1.0 - result.GetNumberOfCells() / before, 4) if before else 0.0
    return _finish(result, _has_normals(polydata), scaled(progress, 0.85, 1.0))


def keep_largest_component(polydata, *, progress: ProgressCallback = None) -> vtkPolyData:
    """Keep only the connected piece with the most triangles (pieces touching at a vertex count as one).

    Unused points are removed; point data (normals, scalars) is kept.
    """
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData, vtkPolyDataConnectivityFilter

    polydata = _checked_polydata(polydata)
    connectivity = vtkPolyDataConnectivityFilter()
    connectivity.SetInputData(polydata)
    connectivity.SetExtractionModeToLargestRegion()
    largest = _detached(run_algorithm(connectivity, scaled(progress, 0.0, 0.6)))
    compact = vtkCleanPolyData()  # drops the points of the other pieces, merges nothing
    compact.SetInputData(largest)
    compact.PointMergingOff()
    compact.ConvertPolysToLinesOff()
    compact.ConvertLinesToPointsOff()
    compact.ConvertStripsToPolysOff()
    return _detached(run_algorithm(compact, scaled(progress, 0.6, 1.0)))


def fill_small_holes(polydata, max_hole_size_mm: float, *, progress: ProgressCallback = None) -> vtkPolyData:
    """Close holes whose rim fits in a sphere of radius ``max_hole_size_mm``; patches wound like their neighbours.

    Parameters
    ----------
    polydata : vtkPolyData
        Triangle surface (mm).
    max_hole_size_mm : float
        Largest hole to fill (``vtkFillHolesFilter.HoleSize``): the radius in mm of a sphere around the hole's rim
        as ``vtkSphere::ComputeBoundingSphere`` estimates it. The estimate is quick, not tight: for a circular
        hole of radius 6 mm it gives 8.8 mm, so allow about 1.5 times the hole's radius.
    progress : callable, optional

    Notes
    -----
    ``vtkFillHolesFilter`` caps each hole with a polygon whose winding is arbitrary; the patches are triangulated
    and ``vtkPolyDataNormals`` (consistency on) turns them to agree with the triangles around them, starting from
    the surface's own triangles, so the surface keeps its orientation. The result has point normals.
    """
    from vtkmodules.vtkFiltersModeling import vtkFillHolesFilter

    polydata = _checked_polydata(polydata)
    if not np.isfinite(max_hole_size_mm) or max_hole_size_mm <= 0:
        raise ValueError(f"max_hole_size_mm must be a positive size in mm, got {max_hole_size_mm!r}")
    filler = vtkFillHolesFilter()
    filler.SetInputData(polydata)
    filler.SetHoleSize(float(max_hole_size_mm))
    filled = surface_compare.triangulated(_detached(run_algorithm(filler, scaled(progress, 0.0, 0.5))))
    return _with_point_normals(filled, scaled(progress, 0.5, 1.0), consistent=True)


@dataclass(frozen=True)
class ValidityReport:
    """Is a surface fit to print, simulate or measure volumes on?

    Attributes
    ----------
    watertight : bool
        Closed: every edge is shared by an even number of triangles (two, or four where voxels meet along an edge).
    manifold : bool
        No edge in three or more triangles and no pinched vertex.
    outward_normals : bool
        Every closed piece faces away from the solid (cavity walls into the cavity), by triangle winding.
    components : int
        Connected pieces.
    points, triangles : int
        Counts.
    area_mm2 : float
        Surface area in mm^2.
    volume_mm3 : float or None
        Enclosed volume in mm^3: only for a watertight surface whose pieces all face outward (cavities inward),
        where it is the volume of the solid; None otherwise (an open or inside-out surface encloses no volume, and
        a number would be a guess).
    """

    watertight: bool
    manifold: bool
    outward_normals: bool
    components: int
    points: int
    triangles: int
    area_mm2: float
    volume_mm3: float | None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        flags = ", ".join(
            f"{'' if ok else 'not '}{name}"
            for name, ok in (("watertight", self.watertight), ("manifold", self.manifold),
                             ("outward", self.outward_normals))
        )
        volume = (f"volume {self.volume_mm3:.1f} mm^3" if self.volume_mm3 is not None
                  else "no enclosed volume (not watertight and outward)")
        return (f"{flags}; {self.components} piece(s), {self.points} points, {self.triangles} triangles, "
                f"area {self.area_mm2:.1f} mm^2, {volume}")


def validity_report(polydata, *, progress: ProgressCallback = None) -> ValidityReport:
    """Topology, orientation, counts, area and volume of a triangle surface (see :class:`ValidityReport`).

    Lean in memory and reporting progress (:func:`app.mesh_validity.validity_numbers`); the progress callback may
    raise :class:`~algorithms.common.progress.OperationCancelled` to stop it.
    """
    polydata = _checked_polydata(polydata)
    points, triangles = polydata_arrays(polydata)
    numbers = validity_numbers(points, triangles, progress=progress)
    edges = numbers["edges"]
    outward = numbers["outward"] and edges.consistently_oriented
    return ValidityReport(
        watertight=edges.watertight,
        manifold=edges.manifold,
        outward_normals=outward,
        components=numbers["components"],
        points=int(points.shape[0]),
        triangles=int(triangles.shape[0]),
        area_mm2=numbers["area_mm2"],
        volume_mm3=numbers["volume_mm3"] if edges.watertight and outward else None,
    )


@dataclass(frozen=True)
class Cleanup:
    """The clean-up steps chosen for an export (the defaults choose none), checked when made: windowed-sinc
    ``smooth_iterations`` with its ``smooth_passband`` in (0, 2], ``decimate`` (the fraction of triangles to remove,
    in [0, 1)), ``largest_component`` (drop islands) and ``fill_holes_mm`` (close holes up to this size)."""

    smooth_iterations: int = 0
    smooth_passband: float = 0.1
    decimate: float = 0.0
    largest_component: bool = False
    fill_holes_mm: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.smooth_iterations, bool) or int(self.smooth_iterations) != self.smooth_iterations \
                or self.smooth_iterations < 0:
            raise ValueError(f"smoothing iterations must be a whole number >= 0, got {self.smooth_iterations!r}")
        if not 0.0 < float(self.smooth_passband) <= 2.0:
            raise ValueError(f"the smoothing pass band must lie in (0, 2], got {self.smooth_passband!r}")
        if not 0.0 <= float(self.decimate) < 1.0:
            raise ValueError(f"decimation is the fraction of triangles to remove, in [0, 1); got {self.decimate!r}")
        if not 0.0 <= float(self.fill_holes_mm) < float("inf"):
            raise ValueError(f"the largest hole to close must be a size >= 0 mm, got {self.fill_holes_mm!r}")

    def chosen(self) -> dict[str, Any]:
        """The chosen steps only, as :func:`apply`'s keywords (what a mesh's sidecar records)."""
        steps: dict[str, Any] = {}
        if self.largest_component:
            steps["largest_component"] = True
        if self.fill_holes_mm:
            steps["fill_holes_mm"] = float(self.fill_holes_mm)
        if self.smooth_iterations:
            steps.update(smooth_iterations=int(self.smooth_iterations), smooth_passband=float(self.smooth_passband))
        if self.decimate:
            steps["decimate"] = float(self.decimate)
        return steps


def apply(
    polydata,
    *,
    smooth_iterations: int = 0,
    smooth_passband: float = 0.1,
    decimate: float = 0.0,
    largest_component: bool = False,
    fill_holes_mm: float = 0.0,
    progress: ProgressCallback = None,
    notes: dict[str, Any] | None = None,
) -> vtkPolyData:
    """Run the chosen clean-up steps in a sensible order: largest piece, fill holes, smooth, decimate.

    ``smooth_iterations=0``, ``decimate=0`` and ``fill_holes_mm=0`` skip those steps. With nothing chosen the
    input is returned unchanged. ``notes`` receives what :func:`decimate` reports. Each step reports progress and
    stops when the progress callback raises :class:`~algorithms.common.progress.OperationCancelled`.
    """
    notes = notes if notes is not None else {}
    steps = []
    if largest_component:
        steps.append(lambda surface, p: keep_largest_component(surface, progress=p))
    if fill_holes_mm:
        steps.append(lambda surface, p: fill_small_holes(surface, fill_holes_mm, progress=p))
    if smooth_iterations:
        steps.append(lambda surface, p: smooth(surface, smooth_iterations, smooth_passband, progress=p))
    if decimate:
        steps.append(lambda surface, p: _decimation(surface, decimate, p, notes))
    for index, step in enumerate(steps):
        polydata = step(polydata, scaled(progress, index / len(steps), (index + 1) / len(steps)))
    report(progress, 1.0)
    return polydata
