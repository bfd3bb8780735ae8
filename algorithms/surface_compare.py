"""Comparing and validating triangle surfaces: the toolkit every surface method's tests and reports use.

Every function takes a surface in any of three forms, turned into arrays by one adapter (:func:`surface_arrays`):
a ``vtkPolyData`` (polygons and strips are triangulated), an object with ``points`` and ``triangles`` attributes
(e.g. :class:`algorithms.marching_cubes.MarchingCubesMesh`), or ``points`` plus ``triangles`` arrays. Points are
``(n, 3)`` coordinates ``(x, y, z)`` in mm; triangles ``(m, 3)`` vertex indices. Results are plain dataclasses.

- :func:`same_triangles`: are two meshes the same triangles, up to triangle order and cyclic vertex order
  (winding must agree), with coordinates within a relative tolerance? Reports what does not match.
- :func:`surface_area` (mm^2), :func:`enclosed_volume` (signed, mm^3, by the divergence theorem).
- :func:`distance_to_surface` (per point, mm, for colouring one surface by its distance to another) and
  :func:`hausdorff` (symmetric Hausdorff and mean surface distance between two surfaces).
- :func:`edge_manifoldness`, :func:`is_watertight`, :func:`is_manifold`, :func:`orientation_outward`,
  :func:`connected_components`.

Notes
-----
Orientation convention (VTK's): a triangle ``(p0, p1, p2)`` faces along ``(p1 - p0) x (p2 - p0)``; a closed surface
whose triangles face outward encloses a positive signed volume. A surface around a cavity (the inner table of a
skull) faces into the cavity, away from the solid, and encloses a *negative* volume; :func:`orientation_outward`
accounts for that by nesting depth.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components as _graph_components
from scipy.spatial import cKDTree
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ._progress import ProgressCallback
from ._vtk import cell_array_from_offsets, polydata_arrays, polydata_from_arrays, run_algorithm

__all__ = [
    "EdgeReport",
    "OrientationReport",
    "SurfaceDistance",
    "TriangleSetComparison",
    "connected_components",
    "distance_to_surface",
    "edge_manifoldness",
    "enclosed_volume",
    "hausdorff",
    "is_manifold",
    "is_watertight",
    "orientation_outward",
    "same_triangles",
    "surface_area",
    "surface_arrays",
    "triangulated",
]


# --------------------------------------------------------------------------------------------------------------
# The adapter
# --------------------------------------------------------------------------------------------------------------
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


def _corners(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]


# --------------------------------------------------------------------------------------------------------------
# Triangle-set comparison
# --------------------------------------------------------------------------------------------------------------
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


# --------------------------------------------------------------------------------------------------------------
# Area and volume
# --------------------------------------------------------------------------------------------------------------
def surface_area(surface, triangles=None) -> float:
    """Total area of the triangles (mm^2)."""
    points, tris = surface_arrays(surface, triangles)
    p0, p1, p2 = _corners(points, tris)
    return float(0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1).sum())


def _signed_volumes(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Signed volume of the tetrahedron (centre, p0, p1, p2) of each triangle, centre = bounding-box centre."""
    if len(tris) == 0:
        return np.zeros(0)
    is_used = np.zeros(points.shape[0], dtype=bool)
    is_used[tris.reshape(-1)] = True
    used = points[is_used]
    centre = 0.5 * (used.min(axis=0) + used.max(axis=0))  # only moves the origin: better rounding, same total
    p0, p1, p2 = _corners(points - centre, tris)
    return np.einsum("ij,ij->i", p0, np.cross(p1, p2)) / 6.0


def enclosed_volume(surface, triangles=None) -> float:
    """Signed volume (mm^3) enclosed by a closed surface, by the divergence theorem.

    Positive when the triangles face outward (counter-clockwise seen from outside). For an open surface the value
    depends on where the surface is open and only approximates the volume of its closure.
    """
    return float(_signed_volumes(*surface_arrays(surface, triangles)).sum())


# --------------------------------------------------------------------------------------------------------------
# Distances
# --------------------------------------------------------------------------------------------------------------
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
    p0, p1, p2 = _corners(unique_points, tris)
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


# --------------------------------------------------------------------------------------------------------------
# Topology
# --------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EdgeReport:
    """Edge and vertex topology of a triangle mesh.

    Attributes
    ----------
    edges : int
        Distinct undirected edges.
    boundary_edges : int
        Edges used by one triangle (the rim of a hole or of an open surface).
    nonmanifold_edges : int
        Edges used by three or more triangles.
    inconsistent_edges : int
        Edges shared by an even number of triangles that do not traverse it as often in one direction as in the
        other (the winding flips across it).
    nonmanifold_vertices : int
        Vertices whose triangles form more than one fan (surfaces touching at a point).
    odd_edges : int
        Edges used by an odd number of triangles: the rim of a hole (one triangle) or a fin (three, five, ...).
    """

    edges: int
    boundary_edges: int
    nonmanifold_edges: int
    inconsistent_edges: int
    nonmanifold_vertices: int
    odd_edges: int

    @property
    def watertight(self) -> bool:
        """Closed: every edge is shared by an even number of triangles.

        Two on a manifold surface; four where two solids touch along an edge, as voxel surfaces do where voxels meet
        only diagonally. Such a surface is closed (it encloses a volume) but not manifold, which :attr:`manifold`
        reports.
        """
        return self.edges > 0 and self.odd_edges == 0

    @property
    def manifold(self) -> bool:
        """No edge with more than two triangles and no pinched vertex (boundaries are allowed)."""
        return self.nonmanifold_edges == 0 and self.nonmanifold_vertices == 0

    @property
    def consistently_oriented(self) -> bool:
        return self.inconsistent_edges == 0


@dataclass
class _Edges:
    """Per-triangle-edge occurrences grouped by undirected edge (internal)."""

    key: np.ndarray  # (3m,) undirected key per occurrence
    forward: np.ndarray  # (3m,) True if the occurrence runs from the lower to the higher vertex index
    unique_keys: np.ndarray
    inverse: np.ndarray  # occurrence -> unique edge
    counts: np.ndarray  # unique edge -> number of occurrences
    order: np.ndarray = field(repr=False)  # occurrences sorted by key


def _edges(points_count: int, tris: np.ndarray) -> _Edges:
    start = tris.reshape(-1)
    end = tris[:, [1, 2, 0]].reshape(-1)
    low, high = np.minimum(start, end), np.maximum(start, end)
    key = low * np.int64(max(points_count, 1)) + high
    order = np.argsort(key, kind="stable")
    unique_keys, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    return _Edges(key, start < end, unique_keys, inverse, counts, order)


def _nonmanifold_vertices(tris: np.ndarray, edges: _Edges) -> int:
    """Vertices around which the triangle corners form more than one edge-connected fan."""
    if len(tris) == 0:
        return 0
    occurrence_count = edges.counts[edges.inverse]
    sorted_occurrences = edges.order[occurrence_count[edges.order] == 2].reshape(-1, 2)  # pairs sharing an edge
    first, second = sorted_occurrences[:, 0], sorted_occurrences[:, 1]
    # Occurrence o is edge o % 3 of triangle o // 3, from corner o % 3 to corner (o + 1) % 3.
    tri1, tri2 = first // 3, second // 3
    start1, end1 = first % 3, (first + 1) % 3
    start2, end2 = second % 3, (second + 1) % 3
    same_direction = edges.forward[first] == edges.forward[second]
    # Match corners by vertex: the start of one occurrence is the start of the other if they run the same way.
    partner_of_start1 = np.where(same_direction, start2, end2)
    partner_of_end1 = np.where(same_direction, end2, start2)
    rows = np.concatenate([3 * tri1 + start1, 3 * tri1 + end1])
    cols = np.concatenate([3 * tri2 + partner_of_start1, 3 * tri2 + partner_of_end1])
    corners = 3 * len(tris)
    graph = sparse.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(corners, corners))
    _, labels = _graph_components(graph, directed=False)
    fans = np.unique(tris.reshape(-1) * np.int64(corners) + labels)  # one entry per (vertex, fan)
    _, fans_per_vertex = np.unique(fans // corners, return_counts=True)
    return int(np.count_nonzero(fans_per_vertex > 1))


def edge_manifoldness(surface, triangles=None) -> EdgeReport:
    """Count boundary, non-manifold and inconsistently oriented edges and pinched vertices."""
    points, tris = surface_arrays(surface, triangles)
    if len(tris) == 0:
        return EdgeReport(0, 0, 0, 0, 0, 0)
    edges = _edges(points.shape[0], tris)
    direction = np.where(edges.forward, 1, -1)
    direction_sum = np.bincount(edges.inverse, weights=direction, minlength=edges.unique_keys.size)
    even = edges.counts % 2 == 0
    return EdgeReport(
        edges=int(edges.unique_keys.size),
        boundary_edges=int(np.count_nonzero(edges.counts == 1)),
        nonmanifold_edges=int(np.count_nonzero(edges.counts > 2)),
        inconsistent_edges=int(np.count_nonzero(even & (direction_sum != 0))),
        nonmanifold_vertices=_nonmanifold_vertices(tris, edges),
        odd_edges=int(np.count_nonzero(~even)),
    )


def is_watertight(surface, triangles=None) -> bool:
    """Closed: every edge is shared by an even number of triangles (see :attr:`EdgeReport.watertight`)."""
    return edge_manifoldness(surface, triangles).watertight


def is_manifold(surface, triangles=None) -> bool:
    """Manifold (with boundary allowed): no edge in three or more triangles, no pinched vertex."""
    return edge_manifoldness(surface, triangles).manifold


def _component_labels(points_count: int, tris: np.ndarray) -> tuple[int, np.ndarray]:
    """Number of vertex-connected triangle components and the component of each triangle."""
    if len(tris) == 0:
        return 0, np.empty(0, dtype=np.int64)
    rows = tris.reshape(-1)
    cols = tris[:, [1, 2, 0]].reshape(-1)
    graph = sparse.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)),
                              shape=(points_count, points_count))
    _, labels = _graph_components(graph, directed=False)
    _, triangle_labels = np.unique(labels[tris[:, 0]], return_inverse=True)
    return int(triangle_labels.max()) + 1, triangle_labels


def connected_components(surface, triangles=None) -> int:
    """Number of pieces of the surface (triangles sharing a vertex belong to the same piece)."""
    points, tris = surface_arrays(surface, triangles)
    return _component_labels(points.shape[0], tris)[0]


@dataclass(frozen=True)
class OrientationReport:
    """Orientation of each connected piece of a surface.

    Attributes
    ----------
    volumes : ndarray (c,)
        Signed enclosed volume of each piece (mm^3).
    closed : ndarray (c,) of bool
        Whether each piece is closed (each of its edges shared by an even number of triangles).
    depth : ndarray (c,) of int
        For closed pieces, how many other closed pieces enclose it (0 for open pieces).
    outward : bool
        Every closed piece faces away from the solid: positive volume at even depth (an outer surface or an island
        in a cavity), negative at odd depth (a cavity's wall). True when there is no closed piece.
    """

    volumes: np.ndarray
    closed: np.ndarray
    depth: np.ndarray
    outward: bool

    @property
    def components(self) -> int:
        return int(self.volumes.size)


def orientation_outward(surface, triangles=None) -> OrientationReport:
    """Check that the triangles of every closed piece face away from the solid (see :class:`OrientationReport`).

    Nesting depth comes from :func:`ray_crossings`: a point of each closed piece is tested against every
    other closed piece whose bounding box contains it.
    """
    points, tris = surface_arrays(surface, triangles)
    count, labels = _component_labels(points.shape[0], tris)
    volumes = np.bincount(labels, weights=_signed_volumes(points, tris), minlength=count)
    edges = _edges(points.shape[0], tris) if len(tris) else None
    closed = np.ones(count, dtype=bool)
    if edges is not None:
        open_edge = edges.counts[edges.inverse] % 2 == 1
        closed[np.unique(np.repeat(labels, 3)[open_edge])] = False
    depth = _nesting_depth(points, tris, labels, closed)
    expected_sign = np.where(depth % 2 == 0, 1.0, -1.0)
    outward = bool(np.all(np.sign(volumes[closed]) == expected_sign[closed]))
    return OrientationReport(volumes=volumes, closed=closed, depth=depth, outward=outward)


def _nesting_depth(points, tris, labels, closed) -> np.ndarray:
    count = closed.size
    depth = np.zeros(count, dtype=np.int64)
    closed_ids = np.flatnonzero(closed)
    if closed_ids.size < 2:
        return depth
    order = np.argsort(labels, kind="stable")
    starts = np.searchsorted(labels[order], np.arange(count + 1))
    corners = points[tris[order]]  # (m, 3, 3), grouped by piece
    piece_low = np.minimum.reduceat(corners.min(axis=1), starts[:-1])
    piece_high = np.maximum.reduceat(corners.max(axis=1), starts[:-1])
    # A point inside one of the piece's triangles: pieces do not touch, so it is inside exactly the pieces that
    # enclose the whole piece.
    probes = corners[starts[closed_ids]].mean(axis=1)
    for outer in closed_ids:
        inside_box = np.all((probes > piece_low[outer]) & (probes < piece_high[outer]), axis=1)
        inside_box &= closed_ids != outer
        if not inside_box.any():
            continue
        crossings = ray_crossings(points, tris[order[starts[outer]:starts[outer + 1]]], probes[inside_box])
        depth[closed_ids[inside_box][crossings % 2 == 1]] += 1
    return depth


def ray_crossings(points: np.ndarray, triangles: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """How many triangles the ray from each origin towards +x passes through.

    For a closed surface an odd count means the origin is enclosed. Rays that meet an edge or a vertex exactly,
    which happens all the time on voxel and grid-aligned surfaces, are decided by simulation of simplicity: the
    origin is moved by ``(0, e, e^2)`` for an infinitesimal ``e``, and each edge's side test is evaluated once,
    from its lower to its higher vertex index, for every triangle that shares it. So a ray through an edge counts
    exactly one of the triangles on each side, and the count is exact for any closed surface, manifold or not.

    Parameters
    ----------
    points : ndarray (n, 3)
    triangles : ndarray (m, 3) of int
        Vertex indices; triangles that share an edge must share its two indices.
    origins : ndarray (k, 3)
        Ray origins; none may lie on the surface.

    Returns
    -------
    ndarray (k,) of int
    """
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    origins = np.atleast_2d(np.asarray(origins, dtype=np.float64))
    result = np.zeros(origins.shape[0], dtype=np.int64)
    if len(triangles) == 0 or len(origins) == 0:
        return result
    corners = points[triangles]  # (m, 3 corners, xyz)
    y_low, y_high = corners[:, :, 1].min(axis=1), corners[:, :, 1].max(axis=1)
    z_low, z_high = corners[:, :, 2].min(axis=1), corners[:, :, 2].max(axis=1)
    # Bucket the triangles on a (y, z) grid with cells as large as the largest triangle: a ray can only meet the
    # triangles whose lower corner lies in its own cell or the cells just below it in y and z.
    cell_y = max(float((y_high - y_low).max()), 1e-12)
    cell_z = max(float((z_high - z_low).max()), 1e-12)
    y0, z0 = float(y_low.min()), float(z_low.min())
    rows = int((y_low.max() - y0) // cell_y) + 2
    bucket = ((z_low - z0) // cell_z).astype(np.int64) * rows + ((y_low - y0) // cell_y).astype(np.int64)
    by_bucket = np.argsort(bucket, kind="stable")
    bucket_sorted = bucket[by_bucket]
    edge_ends = ((0, 1), (1, 2), (2, 0))
    for k, origin in enumerate(origins):
        _, y, z = origin
        row, layer = np.floor((y - y0) / cell_y), np.floor((z - z0) / cell_z)
        if row < 0 or layer < 0 or row > rows:
            continue
        window = []
        for cell in (int(layer) * rows + int(row), int(layer - 1) * rows + int(row)):
            first = np.searchsorted(bucket_sorted, cell - 1, "left")  # this row and the one below
            window.append(by_bucket[first:np.searchsorted(bucket_sorted, cell, "right")])
        window = np.concatenate(window)
        near = window[(z_low[window] <= z) & (z_high[window] >= z) & (y_low[window] <= y) & (y_high[window] >= y)]
        if near.size == 0:
            continue
        tri = triangles[near]
        sides = []
        for i, j in edge_ends:
            forward = tri[:, i] < tri[:, j]
            u = np.where(forward[:, None], corners[near, i], corners[near, j])
            v = np.where(forward[:, None], corners[near, j], corners[near, i])
            side = _perturbed_side(u, v, y, z)
            sides.append(np.where(forward, side, -side))
        inside = (sides[0] == sides[1]) & (sides[1] == sides[2])
        if not inside.any():
            continue
        a, b, c = (corners[near[inside], i] for i in range(3))
        normal = np.cross(b - a, c - a)
        usable = normal[:, 0] != 0.0
        hit_x = a[usable, 0] - (normal[usable, 1] * (y - a[usable, 1])
                                + normal[usable, 2] * (z - a[usable, 2])) / normal[usable, 0]
        result[k] = int(np.count_nonzero(hit_x > origin[0]))
    return result


def _perturbed_side(u: np.ndarray, v: np.ndarray, y: float, z: float) -> np.ndarray:
    """Side (+1 or -1) of the point (y + e, z + e^2) relative to the (y, z) projection of edges u -> v."""
    dy = v[:, 1] - u[:, 1]
    dz = v[:, 2] - u[:, 2]
    side = np.sign(dy * (z - u[:, 2]) - dz * (y - u[:, 1]))
    side = np.where(side != 0, side, np.sign(-dz))  # the e term
    return np.where(side != 0, side, np.sign(dy))  # the e^2 term; zero only for an edge seen end-on
