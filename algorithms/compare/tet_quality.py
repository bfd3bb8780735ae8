"""Quality of tetrahedral meshes: dihedral angles, radius ratio, conformity, boundary fidelity.

Used for our isosurface stuffing and for VTK's tetrahedralisations alike (the same report for both), by tests,
benchmarks, the view's status line and the export sidecar.

- :func:`dihedral_angles` (degrees, six per tetrahedron), :func:`radius_ratios` (3 r_in / r_circ, 1 for the
  regular tetrahedron), :func:`angle_histogram`;
- :func:`check_dihedral_bounds`: the violations of a guaranteed angle range (empty when the guarantee holds);
- :func:`conformity`: faces shared by one, two or more tetrahedra; the boundary closed and outward;
- :func:`boundary_faces`: the faces used once, oriented outward;
- :func:`boundary_fidelity`: distances from a reference surface's vertices to the boundary (fractions within
  given distances, Hausdorff);
- :func:`quality_report`: all of it as a JSON-ready dict.

Arrays: points ``(n, 3)`` float (x, y, z) mm; tetrahedra ``(m, 4)`` int in VTK's order (positive volume).
Imports only :mod:`algorithms.common` (and this family's :mod:`.measures`, :mod:`.topology`).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .measures import distance_to_surface
from .topology import connected_components, orientation_outward

__all__ = ["OUTWARD_FACES", "angle_histogram", "boundary_faces", "boundary_fidelity", "check_dihedral_bounds",
           "conformity", "dihedral_angles", "min_max_dihedral", "quality_report", "radius_ratios"]

#: Outward faces of a tetrahedron ``(0, 1, 2, 3)`` of positive volume.
OUTWARD_FACES = np.array([(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)], dtype=np.int64)
#: The edges of a tetrahedron, opposite to the edges (face pairs) of :data:`OUTWARD_FACES`.
_FACE_PAIRS = [(a, b) for a in range(4) for b in range(a + 1, 4)]
CHUNK = 1_000_000


def _arrays(points, tetrahedra):
    points = np.asarray(points, dtype=np.float64)
    tetrahedra = np.asarray(tetrahedra, dtype=np.int64).reshape(-1, 4)
    return points, tetrahedra


def dihedral_angles(points, tetrahedra) -> np.ndarray:
    """The six interior dihedral angles (degrees) of every tetrahedron, ``(m, 6)`` (float32 to save memory).

    The angle at the edge shared by faces ``a`` and ``b`` is 180 degrees minus the angle between their outward
    normals. Degenerate tetrahedra (a face without area) give NaN.
    """
    points, tetrahedra = _arrays(points, tetrahedra)
    out = np.empty((len(tetrahedra), 6), dtype=np.float32)
    for start in range(0, len(tetrahedra), CHUNK):
        p = points[tetrahedra[start:start + CHUNK]]
        normals = []
        for face in OUTWARD_FACES:
            n = np.cross(p[:, face[1]] - p[:, face[0]], p[:, face[2]] - p[:, face[0]])
            with np.errstate(invalid="ignore", divide="ignore"):
                normals.append(n / np.linalg.norm(n, axis=1)[:, None])
        for column, (a, b) in enumerate(_FACE_PAIRS):
            cosine = np.clip(np.einsum("ij,ij->i", normals[a], normals[b]), -1.0, 1.0)
            out[start:start + CHUNK, column] = 180.0 - np.degrees(np.arccos(cosine))
    return out


def min_max_dihedral(points, tetrahedra) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest dihedral angle (degrees) of every tetrahedron."""
    angles = dihedral_angles(points, tetrahedra)
    return angles.min(axis=1), angles.max(axis=1)


def radius_ratios(points, tetrahedra) -> np.ndarray:
    """``3 r_in / r_circ`` of every tetrahedron (1 for the regular one, 0 for a flat one)."""
    points, tetrahedra = _arrays(points, tetrahedra)
    out = np.empty(len(tetrahedra))
    for start in range(0, len(tetrahedra), CHUNK):
        p = points[tetrahedra[start:start + CHUNK]]
        a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
        volume6 = np.abs(np.einsum("ij,ij->i", np.cross(a, b), c))
        area2 = sum(np.linalg.norm(np.cross(p[:, f[1]] - p[:, f[0]], p[:, f[2]] - p[:, f[0]]), axis=1)
                    for f in OUTWARD_FACES)  # twice the total area
        r_in = volume6 / np.maximum(area2, 1e-300)  # 3V / A = (6V) / (2A)
        # circumcentre offset from p0: solves 2 [a b c]^T x = (|a|^2, |b|^2, |c|^2)
        numerator = (np.einsum("ij,ij->i", a, a)[:, None] * np.cross(b, c)
                     + np.einsum("ij,ij->i", b, b)[:, None] * np.cross(c, a)
                     + np.einsum("ij,ij->i", c, c)[:, None] * np.cross(a, b))
        r_circ = np.linalg.norm(numerator, axis=1) / np.maximum(2.0 * volume6, 1e-300)
        out[start:start + CHUNK] = np.where(r_circ > 0, 3.0 * r_in / np.maximum(r_circ, 1e-300), 0.0)
    return out


def angle_histogram(angles: np.ndarray, *, width: float = 2.0) -> dict[str, list]:
    """Histogram of dihedral angles in bins of ``width`` degrees from 0 to 180: ``{"edges": [...], "counts": [...]}``."""
    edges = np.arange(0.0, 180.0 + width / 2, width)
    counts, _ = np.histogram(np.asarray(angles, dtype=np.float64).ravel(), bins=edges)
    return {"edges": edges.tolist(), "counts": counts.astype(int).tolist()}


def check_dihedral_bounds(points, tetrahedra, low: float, high: float, *, tolerance: float = 1e-6) -> np.ndarray:
    """Indices of the tetrahedra with a dihedral angle outside ``[low, high]`` degrees (or not positive in volume).

    Empty when every tetrahedron keeps the bound: what the tests assert for isosurface stuffing's guarantee.
    """
    points, tetrahedra = _arrays(points, tetrahedra)
    smallest, largest = min_max_dihedral(points, tetrahedra)
    p = points[tetrahedra]
    volume = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    bad = ~(smallest >= low - tolerance) | ~(largest <= high + tolerance) | ~(volume > 0)
    return np.flatnonzero(bad)


def _face_keys(tetrahedra: np.ndarray):
    faces = tetrahedra[:, OUTWARD_FACES].reshape(-1, 3)
    keys = np.sort(faces, axis=1)
    order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
    ordered = keys[order]
    starts = np.concatenate(([True], np.any(ordered[1:] != ordered[:-1], axis=1)))
    group = np.cumsum(starts) - 1
    multiplicity = np.bincount(group)
    return faces, order, group, multiplicity


def boundary_faces(tetrahedra) -> np.ndarray:
    """The faces used by exactly one tetrahedron, oriented outward (counter-clockwise seen from outside)."""
    tetrahedra = np.asarray(tetrahedra, dtype=np.int64).reshape(-1, 4)
    if len(tetrahedra) == 0:
        return np.empty((0, 3), dtype=np.int64)
    faces, order, group, multiplicity = _face_keys(tetrahedra)
    once = multiplicity[group] == 1
    return faces[np.sort(order[once])]


def conformity(points, tetrahedra, *, on_surface: np.ndarray | None = None) -> dict[str, Any]:
    """How the tetrahedra fit together.

    Returns ``interior_faces`` (shared by two), ``boundary_faces`` (used once), ``overshared_faces`` (used by three
    or more: a non-conforming mesh), ``boundary_closed`` (every boundary edge walked as often in one direction as
    in the other by the boundary triangles: closed and consistently oriented), ``nonmanifold_edges`` (boundary
    edges of four or more triangles, where two parts of the solid touch along an edge), ``boundary_outward`` (the boundary encloses positive volume, each closed piece facing
    away from the solid), ``boundary_pieces``, ``conforming`` (no overshared face, closed, outward, every
    tetrahedron of positive volume). With ``on_surface`` (one flag per point: the point lies on the isosurface),
    ``boundary_faces_off_surface`` counts boundary faces with a vertex off the surface: a crack between two
    tetrahedra that split a shared quadrilateral differently leaves such faces, in pairs that close each other, so
    only this finds it. They count against ``conforming``.
    """
    points, tetrahedra = _arrays(points, tetrahedra)
    _, _, _, multiplicity = _face_keys(tetrahedra)
    boundary = boundary_faces(tetrahedra)
    directed = np.concatenate([boundary[:, [0, 1]], boundary[:, [1, 2]], boundary[:, [2, 0]]])
    undirected, inverse = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True)
    forward = (directed[:, 0] < directed[:, 1]).astype(np.int64)
    ahead = np.bincount(inverse.ravel(), weights=forward, minlength=len(undirected))
    total = np.bincount(inverse.ravel(), minlength=len(undirected))
    # closed and consistently oriented: every edge is walked as often one way as the other
    closed = bool(len(boundary) and np.all(2 * ahead == total))
    nonmanifold_edges = int(np.count_nonzero(total > 2))
    p = points[tetrahedra]
    volumes = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0
    orientation = orientation_outward((points, boundary)) if len(boundary) else None
    outward = bool(orientation is not None and orientation.outward and orientation.volumes.sum() > 0)
    report = {
        "interior_faces": int(np.count_nonzero(multiplicity == 2)),
        "boundary_faces": int(np.count_nonzero(multiplicity == 1)),
        "overshared_faces": int(np.count_nonzero(multiplicity > 2)),
        "boundary_closed": closed,
        "nonmanifold_edges": nonmanifold_edges,
        "boundary_outward": outward,
        "boundary_pieces": int(connected_components((points, boundary))) if len(boundary) else 0,
        "nonpositive_tetrahedra": int(np.count_nonzero(volumes <= 0)),
    }
    if on_surface is not None:
        flags = np.asarray(on_surface, dtype=bool)
        report["boundary_faces_off_surface"] = int(np.count_nonzero(~flags[boundary].all(axis=1)))
    report["conforming"] = bool(report["overshared_faces"] == 0 and closed and outward
                                and report["nonpositive_tetrahedra"] == 0
                                and report.get("boundary_faces_off_surface", 0) == 0)
    return report


def boundary_fidelity(reference_points, boundary_points, boundary_triangles, *,
                      within: Sequence[float] = (0.5, 1.0)) -> dict[str, Any]:
    """Distances (mm) from a reference surface's vertices (e.g. marching cubes') to a mesh's boundary.

    Returns ``within_mm`` (the fraction of reference vertices at most each distance away), ``hausdorff_mm`` (the
    largest of those distances and of the boundary vertices' distances back to the reference is not measured here:
    the one-sided maximum), ``mean_mm`` and ``p95_mm``.
    """
    reference_points = np.asarray(reference_points, dtype=np.float64)
    distances = distance_to_surface(reference_points, (np.asarray(boundary_points, dtype=np.float64),
                                                       np.asarray(boundary_triangles, dtype=np.int64)))
    return {
        "within_mm": {f"{d:g}": float(np.mean(distances <= d)) for d in within},
        "max_mm": float(distances.max()) if distances.size else 0.0,
        "mean_mm": float(distances.mean()) if distances.size else 0.0,
        "p95_mm": float(np.percentile(distances, 95)) if distances.size else 0.0,
        "reference_vertices": int(distances.size),
    }


def quality_report(points, tetrahedra, *, bounds: tuple[float, float] | None = None, histogram_width: float = 2.0,
                   with_conformity: bool = True, min_angles: np.ndarray | None = None) -> dict[str, Any]:
    """The quality of a tetrahedral mesh as a JSON-ready dict.

    ``tetrahedra``, ``points``, ``min_dihedral_deg``, ``max_dihedral_deg``, ``histogram`` (2-degree bins of all six
    angles of every tetrahedron), ``under_10_deg`` (fraction of tetrahedra with an angle below 10 degrees),
    ``radius_ratio_min``/``_mean``, ``volume_mm3``, ``min_volume_mm3``, and with ``bounds`` the number of
    tetrahedra outside them (``outside_bounds``); with ``with_conformity`` the keys of :func:`conformity`.
    """
    points, tetrahedra = _arrays(points, tetrahedra)
    report: dict[str, Any] = {"tetrahedra": int(len(tetrahedra)), "points": int(len(points))}
    if len(tetrahedra) == 0:
        return report
    angles = dihedral_angles(points, tetrahedra)
    smallest = np.nanmin(angles, axis=1)
    p = points[tetrahedra]
    volumes = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0
    ratios = radius_ratios(points, tetrahedra)
    report.update({
        "min_dihedral_deg": float(np.nanmin(angles)),
        "max_dihedral_deg": float(np.nanmax(angles)),
        "under_10_deg": float(np.mean(smallest < 10.0)),
        "histogram": angle_histogram(angles, width=histogram_width),
        "radius_ratio_min": float(ratios.min()),
        "radius_ratio_mean": float(ratios.mean()),
        "volume_mm3": float(volumes.sum()),
        "min_volume_mm3": float(volumes.min()),
    })
    if bounds is not None:
        low, high = bounds
        largest = np.nanmax(angles, axis=1)
        report["bounds_deg"] = [float(low), float(high)]
        report["outside_bounds"] = int(np.count_nonzero((smallest < low - 1e-6) | (largest > high + 1e-6)))
    if with_conformity:
        report.update(conformity(points, tetrahedra))
    return report
