"""Measuring surfaces: area, enclosed volume, and distances between two surfaces.

- :func:`surface_area` (mm^2), :func:`enclosed_volume` (signed, mm^3, by the divergence theorem).
- :func:`distance_to_surface` (per point, mm, for colouring one surface by its distance to another) and
  :func:`hausdorff` (symmetric Hausdorff and mean surface distance between two surfaces).

Surfaces in any form :func:`algorithms.compare.triangles.surface_arrays` accepts. A closed surface whose triangles
face outward (VTK's convention) encloses a positive signed volume.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ..common.progress import ProgressCallback
from ..common.vtk_bridge import cell_array_from_offsets, polydata_from_arrays, run_algorithm
from .triangles import corners, surface_arrays

__all__ = ["SurfaceDistance", "distance_to_surface", "enclosed_volume", "hausdorff", "signed_volumes",
           "surface_area"]


def surface_area(surface, triangles=None) -> float:
    """Total area of the triangles (mm^2)."""
    points, tris = surface_arrays(surface, triangles)
    p0, p1, p2 = corners(points, tris)
    return float(0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1).sum())


def signed_volumes(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Signed volume of the tetrahedron (centre, p0, p1, p2) of each triangle, ``(m,)``; the centre is the centre
    of the bounding box of the used points (it only moves the origin: better rounding, same total)."""
    if len(tris) == 0:
        return np.zeros(0)
    is_used = np.zeros(points.shape[0], dtype=bool)
    is_used[tris.reshape(-1)] = True
    used = points[is_used]
    centre = 0.5 * (used.min(axis=0) + used.max(axis=0))  # only moves the origin: better rounding, same total
    p0, p1, p2 = corners(points - centre, tris)
    return np.einsum("ij,ij->i", p0, np.cross(p1, p2)) / 6.0


def enclosed_volume(surface, triangles=None) -> float:
    """Signed volume (mm^3) enclosed by a closed surface, by the divergence theorem.

    Positive when the triangles face outward (counter-clockwise seen from outside). For an open surface the value
    depends on where the surface is open and only approximates the volume of its closure.
    """
    return float(signed_volumes(*surface_arrays(surface, triangles)).sum())


@dataclass(frozen=True)
class SurfaceDistance:
    """Distances between two surfaces a and b (mm), measured from the vertices of each to the other surface.

    ``hausdorff`` is the larger of the two one-sided maxima; ``mean`` is the average over the vertices of both
    (the average symmetric surface distance).
    """

    hausdorff: float
    mean: float
    a_to_b_max: float
    b_to_a_max: float
    a_to_b_mean: float
    b_to_a_mean: float


def distance_to_surface(points, reference, *, signed: bool = False, progress: ProgressCallback = None) -> np.ndarray:
    """Distance (mm) from each point to the nearest point of the reference surface's triangles.

    Parameters
    ----------
    points : array (n, 3)
        Query points in mm.
    reference : surface
        Any accepted surface form (see :func:`surface_arrays`).
    signed : bool
        Negative inside the reference (which must then be closed and face outward), as
        ``vtkImplicitPolyDataDistance`` decides from angle-weighted pseudo-normals.
    progress : callable, optional
        Forwarded to the VTK filter.

    Returns
    -------
    ndarray, shape (n,), float64

    Notes
    -----
    Runs ``vtkDistancePolyDataFilter`` (``vtkImplicitPolyDataDistance`` at every point). Coincident points of the
    reference are merged and triangles without area dropped first: they change no distance, and VTK 9.7 reads
    invalid point ids (and crashes, depending on memory layout) in ``vtkImplicitPolyDataDistance::SharedEvaluate``
    when the closest point lies on a degenerate triangle, as ``vtkFlyingEdges3D`` makes where the isovalue equals
    sample values.
    """
    from vtkmodules.vtkFiltersGeneral import vtkDistancePolyDataFilter

    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {points.shape}")
    reference = _without_degenerate_triangles(*surface_arrays(reference))
    if reference.GetNumberOfPolys() == 0:
        raise ValueError("the reference surface has no triangles with an area")
    if points.shape[0] == 0:
        return np.empty(0)
    queries = polydata_from_arrays(points, np.empty((0, 3), dtype=np.int64))
    queries.SetVerts(cell_array_from_offsets(np.arange(points.shape[0] + 1), np.arange(points.shape[0])))
    distance = vtkDistancePolyDataFilter()
    distance.SetInputData(0, queries)
    distance.SetInputData(1, reference)
    distance.SetSignedDistance(signed)
    distance.ComputeSecondDistanceOff()
    distance.ComputeCellCenterDistanceOff()
    output = run_algorithm(distance, progress)
    return numpy_support.vtk_to_numpy(output.GetPointData().GetArray("Distance")).copy()


def _without_degenerate_triangles(points: np.ndarray, tris: np.ndarray) -> vtkPolyData:
    """The surface with coincident points merged and triangles of zero area removed."""
    unique_points, index = np.unique(points, axis=0, return_inverse=True)
    tris = index.reshape(-1)[tris]
    p0, p1, p2 = corners(unique_points, tris)
    has_area = np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1) > 0
    return polydata_from_arrays(unique_points, tris[has_area])


def hausdorff(surface_a, surface_b, *, progress: ProgressCallback = None) -> SurfaceDistance:
    """Symmetric Hausdorff distance and mean surface distance (mm) between two surfaces.

    Vertex-sampled: the distance from every vertex (used by a triangle) of a to the triangles of b, and back. The
    true Hausdorff distance can exceed this by at most the largest triangle's size.
    """
    points_a, tris_a = surface_arrays(surface_a)
    points_b, tris_b = surface_arrays(surface_b)
    if len(tris_a) == 0 or len(tris_b) == 0:
        raise ValueError("both surfaces need triangles to measure distances between them")
    half = None if progress is None else (lambda f: progress(0.5 * f))
    a_to_b = distance_to_surface(points_a[np.unique(tris_a)], (points_b, tris_b), progress=half)
    b_to_a = distance_to_surface(points_b[np.unique(tris_b)], (points_a, tris_a),
                                 progress=None if progress is None else (lambda f: progress(0.5 + 0.5 * f)))
    return SurfaceDistance(
        hausdorff=float(max(a_to_b.max(), b_to_a.max())),
        mean=float((a_to_b.sum() + b_to_a.sum()) / (a_to_b.size + b_to_a.size)),
        a_to_b_max=float(a_to_b.max()),
        b_to_a_max=float(b_to_a.max()),
        a_to_b_mean=float(a_to_b.mean()),
        b_to_a_mean=float(b_to_a.mean()),
    )
