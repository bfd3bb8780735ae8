"""The quality toolkit on tetrahedra with known answers, and VTK's tetrahedralisations run as references."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from algorithms.common.mesh import TetMesh
from algorithms.compare.tet_quality import (
    boundary_faces,
    conformity,
    dihedral_angles,
    quality_report,
    radius_ratios,
)
from algorithms.references.vtk_tetrahedra import vtk_clip_tetrahedra, vtk_delaunay_tetrahedra, vtk_min_dihedral

REGULAR = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64)
CORNER = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)


def _oriented(points):
    tets = np.array([[0, 1, 2, 3]])
    return tets if TetMesh(points, tets).volumes()[0] > 0 else tets[:, [1, 0, 2, 3]]


def _edge_projection_angles(points):
    """Dihedral angles by an independent formula: the angle between the other two vertices projected on the
    plane normal to each edge."""
    out = []
    for i, j in itertools.combinations(range(4), 2):
        k, l = [v for v in range(4) if v not in (i, j)]
        e = (points[j] - points[i]) / np.linalg.norm(points[j] - points[i])
        u = points[k] - points[i] - np.dot(points[k] - points[i], e) * e
        v = points[l] - points[i] - np.dot(points[l] - points[i], e) * e
        out.append(np.degrees(np.arccos(np.dot(u, v) / np.linalg.norm(u) / np.linalg.norm(v))))
    return np.sort(out)


@pytest.mark.parametrize("points", [REGULAR, CORNER, np.random.default_rng(1).normal(size=(4, 3))])
def test_dihedral_angles_match_an_independent_formula_and_vtk_on_known_tetrahedra(points):
    tets = _oriented(points)
    ours = np.sort(dihedral_angles(points, tets)[0])
    np.testing.assert_allclose(ours, _edge_projection_angles(points), atol=1e-4)
    if points is not CORNER and points is not REGULAR:
        return
    np.testing.assert_allclose(vtk_min_dihedral(TetMesh(points, tets)), ours.min(), atol=1e-4)


def test_regular_tetrahedron_numbers():
    tets = _oriented(REGULAR)
    np.testing.assert_allclose(dihedral_angles(REGULAR, tets), np.degrees(np.arccos(1 / 3)), atol=1e-4)
    assert radius_ratios(REGULAR, tets)[0] == pytest.approx(1.0)
    assert radius_ratios(CORNER, _oriented(CORNER))[0] < 1.0


def test_conformity_of_a_cube_split_into_six_and_of_a_broken_one():
    cube = np.array(list(itertools.product((0.0, 1.0), repeat=3)))[:, ::-1]  # x fastest
    # the six tetrahedra about the diagonal 0-7
    paths = [(1, 3), (3, 2), (2, 6), (6, 4), (4, 5), (5, 1)]
    tets = np.array([[0, a, b, 7] for a, b in paths])
    tets = np.array([t if TetMesh(cube, t[None]).volumes()[0] > 0 else t[[1, 0, 2, 3]] for t in tets])
    report = conformity(cube, tets)
    assert report["conforming"] and report["boundary_faces"] == 12 and report["interior_faces"] == 6
    assert boundary_faces(tets).shape == (12, 3)
    broken = conformity(cube, tets[1:])
    assert broken["boundary_faces"] == 12 and broken["interior_faces"] == 4 and broken["conforming"]  # a notch
    flipped = tets.copy()
    flipped[0] = flipped[0, [1, 0, 2, 3]]
    assert not conformity(cube, flipped)["conforming"]


def _sphere(n=40, r=12.0):
    axis = np.arange(n, dtype=np.float32) - (n - 1) / 2
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    return r - np.sqrt(x * x + y * y + z * z), (-(n - 1) / 2,) * 3


def test_vtk_delaunay_keeps_the_inside_and_clip_volume_gives_tetrahedra():
    field, origin = _sphere()
    delaunay = vtk_delaunay_tetrahedra(field, 0.0, origin=origin)
    assert 0 < delaunay.mesh.n_tetrahedra <= delaunay.stats["hull_tetrahedra"]
    clip = vtk_clip_tetrahedra(field, 0.0, origin=origin)
    exact = 4 / 3 * np.pi * 12.0 ** 3
    for result in (delaunay, clip):
        report = quality_report(result.mesh.points, result.mesh.tetrahedra)
        assert report["volume_mm3"] == pytest.approx(exact, rel=0.03)
        assert report["nonpositive_tetrahedra"] == 0
    assert quality_report(clip.mesh.points, clip.mesh.tetrahedra)["min_dihedral_deg"] < 10.7
