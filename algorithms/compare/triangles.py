"""Surfaces as arrays, and whether two surfaces are the same triangles.

Every function of :mod:`algorithms.compare` takes a surface in any of three forms, turned into arrays by one
adapter (:func:`surface_arrays`): a ``vtkPolyData`` (polygons and strips are triangulated), an object with
``points`` and ``triangles`` attributes (e.g. a :class:`algorithms.common.mesh.TriangleMesh`), or ``points`` plus
``triangles`` arrays. Points are ``(n, 3)`` coordinates ``(x, y, z)`` in mm; triangles ``(m, 3)`` vertex indices.

:func:`same_triangles`: are two meshes the same triangles, up to triangle order and cyclic vertex order (winding
must agree), with coordinates within a relative tolerance? Reports what does not match.

Orientation convention (VTK's): a triangle ``(p0, p1, p2)`` faces along ``(p1 - p0) x (p2 - p0)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ..common.vtk_bridge import polydata_arrays, run_algorithm

__all__ = ["TriangleSetComparison", "corners", "same_triangles", "surface_arrays", "triangulated"]


def surface_arrays(surface, triangles=None) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(n, 3)`` float64 and triangles ``(m, 3)`` int64 of any accepted surface form.

    Parameters
    ----------
    surface : vtkPolyData, object with ``points`` and ``triangles``, (points, triangles) tuple, or points array
        The surface. A ``vtkPolyData`` may hold triangles, other polygons and strips (triangulated here; vertices
        and lines are ignored). A points array needs ``triangles``.
    triangles : array (m, 3), optional
        Vertex indices, only together with a points array.
    """
    if isinstance(surface, vtkPolyData):
        if triangles is not None:
            raise ValueError("give triangles only with a points array, not with a vtkPolyData")
        points, tris = polydata_arrays(triangulated(surface))
    elif triangles is not None:
        points, tris = surface, triangles
    elif hasattr(surface, "points") and hasattr(surface, "triangles"):
        points, tris = surface.points, surface.triangles
    elif isinstance(surface, tuple) and len(surface) == 2:
        points, tris = surface
    else:
        raise ValueError(
            "a surface is a vtkPolyData, an object with points and triangles, or points with triangles; "
            f"got {type(surface).__name__}"
        )
    points = np.asarray(points, dtype=np.float64)
    tris = np.asarray(tris)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {points.shape}")
    if tris.size == 0:
        tris = tris.reshape(0, 3)
    if tris.ndim != 2 or tris.shape[1] != 3 or tris.dtype.kind not in "iu":
        raise ValueError(f"triangles must be integer indices of shape (m, 3), got {tris.dtype} {tris.shape}")
    tris = tris.astype(np.int64, copy=False)
    if tris.size and (tris.min() < 0 or tris.max() >= points.shape[0]):
        raise ValueError(f"triangle indices must lie in [0, {points.shape[0]}), got {tris.min()}..{tris.max()}")
    return points, tris


def triangulated(polydata: vtkPolyData) -> vtkPolyData:
    """The surface as triangles only: strips and larger polygons are split by ``vtkTriangleFilter`` when present.

    Returns the input itself when it already holds only triangles (vertices and lines are dropped otherwise).
    """
    polys = polydata.GetPolys()
    only_triangles = polydata.GetNumberOfStrips() == 0 and (
        polys is None
        or polys.GetNumberOfCells() == 0
        or np.all(np.diff(numpy_support.vtk_to_numpy(polys.GetOffsetsArray())) == 3)
    )
    if only_triangles:
        return polydata
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter

    triangulate = vtkTriangleFilter()
    triangulate.SetInputData(polydata)
    triangulate.PassVertsOff()
    triangulate.PassLinesOff()
    return run_algorithm(triangulate)


def corners(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three corner positions ``(p0, p1, p2)`` of every triangle, each ``(m, 3)``."""
    return points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]


@dataclass(frozen=True)
class TriangleSetComparison:
    """Result of :func:`same_triangles`.

    Attributes
    ----------
    equal : bool
        Every triangle of each mesh has a distinct partner in the other (one to one).
    count_a, count_b : int
        Triangles in each mesh.
    unmatched_a, unmatched_b : ndarray of int
        Indices of triangles without a partner.
    reversed_a : ndarray of int
        Indices (subset of ``unmatched_a``) of triangles that match an unmatched triangle of b with the opposite
        winding.
    tolerance : float
        Largest allowed distance (mm) between corresponding vertices.
    max_distance : float
        Largest distance (mm) between corresponding vertices of matched triangles.
    """

    equal: bool
    count_a: int
    count_b: int
    unmatched_a: np.ndarray
    unmatched_b: np.ndarray
    reversed_a: np.ndarray
    tolerance: float
    max_distance: float

    def summary(self) -> str:
        """One line for a report or an assertion message."""
        return (
            f"{self.count_a} vs {self.count_b} triangles: {len(self.unmatched_a)} of a and {len(self.unmatched_b)} "
            f"of b unmatched ({len(self.reversed_a)} of a reversed); max vertex distance {self.max_distance:.3g} mm "
            f"(tolerance {self.tolerance:.3g} mm)"
        )


def _rotation_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest vertex distance between triangles a[i] and b[i] for each cyclic rotation of b, shape (len, 3)."""
    return np.stack(
        [np.linalg.norm(a - np.roll(b, -shift, axis=1), axis=2).max(axis=1) for shift in range(3)], axis=1
    )


def same_triangles(points_a, tris_a, points_b, tris_b, *, rtol: float = 1e-5) -> TriangleSetComparison:
    """Compare two triangle sets independently of triangle order and of where each triangle's vertex cycle starts.

    Parameters
    ----------
    points_a, points_b : array (n, 3)
        Vertex coordinates (mm).
    tris_a, tris_b : array (m, 3)
        Triangles as vertex indices. Two triangles correspond when their vertices agree after a cyclic rotation
        (the winding must agree; reversed matches are reported separately).
    rtol : float
        Tolerance relative to the size of the meshes: corresponding vertices may be ``rtol`` times the diagonal of
        the common bounding box apart.

    Returns
    -------
    TriangleSetComparison

    Raises
    ------
    ValueError
        If ``rtol`` is negative or not finite, or the arrays are malformed.

    Notes
    -----
    Candidates are found by a k-d tree on triangle centroids (corresponding centroids are within the tolerance of
    each other), then checked vertex by vertex for the three rotations; every triangle is used at most once, so
    duplicated triangles must be duplicated on both sides.
    """
    if not np.isfinite(rtol) or rtol < 0:
        raise ValueError(f"rtol must be a finite number >= 0, got {rtol}")
    points_a, tris_a = surface_arrays(points_a, tris_a)
    points_b, tris_b = surface_arrays(points_b, tris_b)
    corners_a, corners_b = points_a[tris_a], points_b[tris_b]  # (m, 3, 3)
    everything = np.concatenate([corners_a.reshape(-1, 3), corners_b.reshape(-1, 3)])
    diagonal = float(np.linalg.norm(everything.max(axis=0) - everything.min(axis=0))) if everything.size else 0.0
    tolerance = rtol * diagonal
    search_radius = tolerance + 1e-12 * max(diagonal, 1.0)  # centroids of partners are within the tolerance
    empty = np.empty(0, dtype=np.int64)
    if len(tris_a) == 0 or len(tris_b) == 0:
        return TriangleSetComparison(
            len(tris_a) == len(tris_b), len(tris_a), len(tris_b), np.arange(len(tris_a)), np.arange(len(tris_b)),
            empty, tolerance, 0.0,
        )

    centroids_b = corners_b.mean(axis=1)
    tree = cKDTree(centroids_b)
    partner = np.full(len(tris_a), -1, dtype=np.int64)
    distance = np.zeros(len(tris_a))
    # Fast path: the nearest centroid is the partner, unless several triangles of a claim the same one.
    _, nearest = tree.query(corners_a.mean(axis=1))
    best = _rotation_distances(corners_a, corners_b[nearest]).min(axis=1)
    good = best <= tolerance
    claimed, claims = np.unique(nearest[good], return_counts=True)
    unique_claim = good & np.isin(nearest, claimed[claims == 1])
    partner[unique_claim] = nearest[unique_claim]
    distance[unique_claim] = best[unique_claim]
    used = np.zeros(len(tris_b), dtype=bool)
    used[partner[unique_claim]] = True
    # Slow path for the rest: every candidate whose centroid is within the tolerance.
    for index in np.flatnonzero(~unique_claim):
        centroid = corners_a[index].mean(axis=0)
        for candidate in tree.query_ball_point(centroid, search_radius):
            if used[candidate]:
                continue
            gap = _rotation_distances(corners_a[index:index + 1], corners_b[candidate:candidate + 1]).min()
            if gap <= tolerance:
                partner[index], distance[index], used[candidate] = candidate, gap, True
                break
    unmatched_a = np.flatnonzero(partner < 0)
    unmatched_b = np.flatnonzero(~used)
    reversed_a = _reversed_matches(corners_a[unmatched_a], corners_b[unmatched_b], tolerance, search_radius)
    return TriangleSetComparison(
        equal=unmatched_a.size == 0 and unmatched_b.size == 0,
        count_a=len(tris_a),
        count_b=len(tris_b),
        unmatched_a=unmatched_a,
        unmatched_b=unmatched_b,
        reversed_a=unmatched_a[reversed_a],
        tolerance=tolerance,
        max_distance=float(distance[partner >= 0].max()) if np.any(partner >= 0) else 0.0,
    )


def _reversed_matches(corners_a: np.ndarray, corners_b: np.ndarray, tolerance: float, radius: float) -> np.ndarray:
    """Positions in ``corners_a`` of triangles equal to some triangle of ``corners_b`` with reversed winding."""
    if len(corners_a) == 0 or len(corners_b) == 0:
        return np.empty(0, dtype=np.int64)
    flipped_b = corners_b[:, ::-1]
    tree = cKDTree(flipped_b.mean(axis=1))
    found = []
    for index, triangle in enumerate(corners_a):
        for candidate in tree.query_ball_point(triangle.mean(axis=0), radius):
            if _rotation_distances(triangle[None], flipped_b[candidate][None]).min() <= tolerance:
                found.append(index)
                break
    return np.asarray(found, dtype=np.int64)
