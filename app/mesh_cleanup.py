"""Clinician-ready post-processing of extracted surfaces, headless: smoothing, decimation, clean-up, validation.

Each step takes a triangle ``vtkPolyData`` (strips and polygons are triangulated first) in millimetres and returns
a new one, running VTK's filter through :func:`algorithms.common.vtk_bridge.run_algorithm`, so progress is forwarded
and VTK errors become exceptions. Steps that move points recompute point normals when the input had them (stale normals
would shade the old shape); winding is never changed except by :func:`fill_small_holes`, which makes the patches
agree with their surroundings.

- :func:`smooth`: windowed-sinc low-pass (Taubin et al.), no shrinkage; ``vtkWindowedSincPolyDataFilter``.
- :func:`decimate`: quadric error decimation (Garland & Heckbert 1997) preserving volume; ``vtkQuadricDecimation``.
- :func:`keep_largest_component`: drop islands (noise, loose fragments); ``vtkPolyDataConnectivityFilter``.
- :func:`fill_small_holes`: close holes up to a size, e.g. where a surface meets the edge of the scan;
  ``vtkFillHolesFilter``.
- :func:`validity_report`: watertight, manifold, outward, pieces, counts, area and volume, from
  :mod:`algorithms.compare`.
- :func:`apply`: the steps chosen for an export, in that order (largest piece, holes, smoothing, decimation).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkPolyData

from algorithms import compare as surface_compare
from algorithms.common.progress import ProgressCallback, report, scaled
from algorithms.common.vtk_bridge import run_algorithm

__all__ = [
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


def _with_point_normals(polydata: vtkPolyData, progress: ProgressCallback) -> vtkPolyData:
    """Point normals recomputed from the triangles, winding kept as it is (no reordering, no splitting)."""
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals

    normals = vtkPolyDataNormals()
    normals.SetInputData(_without_point_normals(polydata))
    normals.ComputePointNormalsOn()
    normals.ComputeCellNormalsOff()
    normals.SplittingOff()
    normals.ConsistencyOff()
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


def decimate(polydata, target_reduction: float, *, progress: ProgressCallback = None) -> vtkPolyData:
    """Reduce the number of triangles by quadric error decimation, preserving the enclosed volume.

    Parameters
    ----------
    polydata : vtkPolyData
        Triangle surface (mm).
    target_reduction : float
        Fraction of triangles to remove, in [0, 1): 0.75 keeps about a quarter.
    progress : callable, optional

    Notes
    -----
    M. Garland, P. S. Heckbert, "Surface simplification using quadric error metrics", SIGGRAPH 1997,
    doi:10.1145/258734.258849. Volume preservation as in Lindstrom & Turk 1998.
    """
    return _quadric_decimation(polydata, target_reduction, progress)


def _quadric_decimation(polydata, target_reduction: float, progress: ProgressCallback) -> vtkPolyData:
    """:func:`decimate`'s body (also reached from :func:`apply`, whose ``decimate`` argument hides the name)."""
    from vtkmodules.vtkFiltersCore import vtkQuadricDecimation

    polydata = _checked_polydata(polydata)
    if not np.isfinite(target_reduction) or not 0.0 <= target_reduction < 1.0:
        raise ValueError(f"target_reduction is the fraction of triangles to remove, in [0, 1); got {target_reduction!r}")
    decimator = vtkQuadricDecimation()
    decimator.SetInputData(polydata)
    decimator.SetTargetReduction(float(target_reduction))
    decimator.VolumePreservationOn()
    result = _detached(run_algorithm(decimator, scaled(progress, 0.0, 0.9)))
    return _finish(result, _has_normals(polydata), scaled(progress, 0.9, 1.0))


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
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
    from vtkmodules.vtkFiltersModeling import vtkFillHolesFilter

    polydata = _checked_polydata(polydata)
    if not np.isfinite(max_hole_size_mm) or max_hole_size_mm <= 0:
        raise ValueError(f"max_hole_size_mm must be a positive size in mm, got {max_hole_size_mm!r}")
    filler = vtkFillHolesFilter()
    filler.SetInputData(polydata)
    filler.SetHoleSize(float(max_hole_size_mm))
    filled = surface_compare.triangulated(_detached(run_algorithm(filler, scaled(progress, 0.0, 0.5))))
    normals = vtkPolyDataNormals()
    normals.SetInputData(_without_point_normals(filled))
    normals.ConsistencyOn()
    normals.AutoOrientNormalsOff()
    normals.SplittingOff()
    normals.ComputePointNormalsOn()
    normals.ComputeCellNormalsOff()
    return _detached(run_algorithm(normals, scaled(progress, 0.5, 1.0)))


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
    volume_mm3 : float
        Signed enclosed volume in mm^3 (meaningful when watertight).
    """

    watertight: bool
    manifold: bool
    outward_normals: bool
    components: int
    points: int
    triangles: int
    area_mm2: float
    volume_mm3: float

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        flags = ", ".join(
            f"{'' if ok else 'not '}{name}"
            for name, ok in (("watertight", self.watertight), ("manifold", self.manifold),
                             ("outward", self.outward_normals))
        )
        return (f"{flags}; {self.components} piece(s), {self.points} points, {self.triangles} triangles, "
                f"area {self.area_mm2:.1f} mm^2, volume {self.volume_mm3:.1f} mm^3")


def validity_report(polydata) -> ValidityReport:
    """Topology, orientation, counts, area and volume of a triangle surface (see :class:`ValidityReport`)."""
    polydata = _checked_polydata(polydata)
    points, triangles = surface_compare.surface_arrays(polydata)
    edges = surface_compare.edge_manifoldness(points, triangles)
    orientation = surface_compare.orientation_outward(points, triangles)
    return ValidityReport(
        watertight=edges.watertight,
        manifold=edges.manifold,
        outward_normals=orientation.outward and edges.consistently_oriented,
        components=orientation.components,
        points=int(points.shape[0]),
        triangles=int(triangles.shape[0]),
        area_mm2=surface_compare.surface_area(points, triangles),
        volume_mm3=surface_compare.enclosed_volume(points, triangles),
    )


def apply(
    polydata,
    *,
    smooth_iterations: int = 0,
    smooth_passband: float = 0.1,
    decimate: float = 0.0,
    largest_component: bool = False,
    fill_holes_mm: float = 0.0,
    progress: ProgressCallback = None,
) -> vtkPolyData:
    """Run the chosen clean-up steps in a sensible order: largest piece, fill holes, smooth, decimate.

    ``smooth_iterations=0``, ``decimate=0`` and ``fill_holes_mm=0`` skip those steps. With nothing chosen the
    input is returned unchanged.
    """
    steps = []
    if largest_component:
        steps.append(lambda surface, p: keep_largest_component(surface, progress=p))
    if fill_holes_mm:
        steps.append(lambda surface, p: fill_small_holes(surface, fill_holes_mm, progress=p))
    if smooth_iterations:
        steps.append(lambda surface, p: smooth(surface, smooth_iterations, smooth_passband, progress=p))
    if decimate:
        steps.append(lambda surface, p: _quadric_decimation(surface, decimate, p))
    for index, step in enumerate(steps):
        polydata = step(polydata, scaled(progress, index / len(steps), (index + 1) / len(steps)))
    report(progress, 1.0)
    return polydata
