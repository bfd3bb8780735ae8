"""The surface toolkit on meshes with known answers: cubes, nested and touching cubes, spheres."""

from __future__ import annotations

import numpy as np
import pytest
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

from algorithms import compare as sc
from algorithms.common.vtk_bridge import polydata_from_arrays
from algorithms.datasets.volumes import sphere_field
from algorithms.surfaces.marching_cubes import marching_cubes

CUBE_POINTS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64
)
# Two triangles per face, counter-clockwise seen from outside.
CUBE_TRIANGLES = np.array(
    [
        [0, 2, 1], [0, 3, 2],  # z = 0
        [4, 5, 6], [4, 6, 7],  # z = 1
        [0, 1, 5], [0, 5, 4],  # y = 0
        [3, 7, 6], [3, 6, 2],  # y = 1
        [0, 4, 7], [0, 7, 3],  # x = 0
        [1, 2, 6], [1, 6, 5],  # x = 1
    ]
)


def cube(centre=(0.5, 0.5, 0.5), size=1.0, *, inward=False):
    points = (CUBE_POINTS - 0.5) * size + np.asarray(centre, dtype=np.float64)
    triangles = CUBE_TRIANGLES[:, ::-1] if inward else CUBE_TRIANGLES
    return points, triangles.copy()


def union(*meshes):
    points, triangles, offset = [], [], 0
    for p, t in meshes:
        points.append(p)
        triangles.append(t + offset)
        offset += len(p)
    return np.concatenate(points), np.concatenate(triangles)


# --------------------------------------------------------------------------------------------------------------
# Adapter
# --------------------------------------------------------------------------------------------------------------
def test_every_surface_form_gives_the_same_arrays():
    points, triangles = cube()
    mesh = marching_cubes(sphere_field((10, 10, 10), 3.0), 0.0)
    for surface in (polydata_from_arrays(points, triangles), (points, triangles)):
        p, t = sc.surface_arrays(surface)
        assert p.dtype == np.float64 and t.dtype == np.int64
        assert np.array_equal(p, points) and np.array_equal(t, triangles)
    p, t = sc.surface_arrays(points.astype(np.float32), triangles.astype(np.int32))
    assert np.array_equal(p, points) and np.array_equal(t, triangles)
    p, t = sc.surface_arrays(mesh)
    assert np.array_equal(p, mesh.points) and np.array_equal(t, mesh.triangles)


def test_strips_and_quads_are_triangulated():
    vtk_points = vtkPoints()
    for p in ([0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0], [1, 2, 0]):
        vtk_points.InsertNextPoint(*p)
    strips = vtkCellArray()
    strips.InsertNextCell(6, [0, 1, 2, 3, 4, 5])
    quads = vtkCellArray()
    quads.InsertNextCell(4, [0, 1, 3, 2])
    polydata = vtkPolyData()
    polydata.SetPoints(vtk_points)
    polydata.SetStrips(strips)
    assert sc.surface_area(polydata) == pytest.approx(2.0)
    polydata.SetStrips(vtkCellArray())
    polydata.SetPolys(quads)
    assert sc.surface_arrays(polydata)[1].shape == (2, 3)
    assert sc.triangulated(polydata) is not polydata
    triangles_only = polydata_from_arrays(*cube())
    assert sc.triangulated(triangles_only) is triangles_only


@pytest.mark.parametrize(
    "surface, triangles, message",
    [
        ("not a surface", None, "a surface is"),
        (np.zeros((3, 2)), np.array([[0, 1, 2]]), "points must have shape"),
        (np.zeros((3, 3)), np.array([[0.0, 1.0, 2.0]]), "integer indices"),
        (np.zeros((3, 3)), np.array([[0, 1, 3]]), "must lie in"),
        (polydata_from_arrays(*cube()), np.array([[0, 1, 2]]), "only with a points array"),
    ],
)
def test_adapter_errors(surface, triangles, message):
    with pytest.raises(ValueError, match=message):
        sc.surface_arrays(surface, triangles)


# --------------------------------------------------------------------------------------------------------------
# Triangle-set comparison
# --------------------------------------------------------------------------------------------------------------
def test_same_triangles_ignores_order_and_starting_vertex():
    rng = np.random.default_rng(0)
    mesh = marching_cubes(sphere_field((16, 16, 16), 5.0), 0.0)
    order = rng.permutation(len(mesh.points))
    renumbered = np.argsort(order)[mesh.triangles]  # the same triangles on the points in another order
    shuffled = np.roll(renumbered[rng.permutation(len(renumbered))], 1, axis=1)
    result = sc.same_triangles(mesh.points, mesh.triangles, mesh.points[order], shuffled)
    assert result.equal and result.max_distance == 0.0 and result.count_a == result.count_b == len(mesh.triangles)


def test_same_triangles_reports_mismatches():
    points, triangles = cube()
    flipped = triangles.copy()
    flipped[3] = flipped[3, ::-1]
    result = sc.same_triangles(points, triangles, points, flipped)
    assert not result.equal
    assert result.unmatched_a.tolist() == [3] and result.unmatched_b.tolist() == [3]
    assert result.reversed_a.tolist() == [3]
    assert "1 of a and 1 of b unmatched" in result.summary()

    moved = points.copy()
    moved[6] += 1e-3  # corner (1, 1, 1), used by 6 triangles; the tolerance is 1e-5 * sqrt(3)
    result = sc.same_triangles(points, triangles, moved, triangles)
    assert sorted(result.unmatched_a.tolist()) == sorted(np.flatnonzero((triangles == 6).any(axis=1)).tolist())
    result = sc.same_triangles(points, triangles, moved, triangles, rtol=1e-3)
    assert result.equal and result.max_distance == pytest.approx(np.sqrt(3) * 1e-3, rel=1e-6)


def test_same_triangles_counts_duplicates():
    points, triangles = cube()
    doubled = np.concatenate([triangles, triangles[:1]])
    result = sc.same_triangles(points, doubled, points, triangles)
    assert not result.equal and len(result.unmatched_a) == 1 and len(result.unmatched_b) == 0
    assert sc.same_triangles(points, doubled, points, doubled[::-1]).equal


def test_same_triangles_with_empty_meshes_and_bad_tolerance():
    points, triangles = cube()
    empty = np.empty((0, 3), dtype=np.int64)
    assert sc.same_triangles(points, empty, points, empty).equal
    result = sc.same_triangles(points, triangles, points, empty)
    assert not result.equal and len(result.unmatched_a) == 12
    for rtol in (-1e-5, np.nan):
        with pytest.raises(ValueError, match="rtol"):
            sc.same_triangles(points, triangles, points, triangles, rtol=rtol)


# --------------------------------------------------------------------------------------------------------------
# Area, volume, distances
# --------------------------------------------------------------------------------------------------------------
def test_area_and_signed_volume_of_cubes():
    points, triangles = cube(centre=(100.0, -50.0, 7.0), size=2.0)
    assert sc.surface_area(points, triangles) == pytest.approx(24.0)
    assert sc.enclosed_volume(points, triangles) == pytest.approx(8.0)
    assert sc.enclosed_volume(*cube(inward=True)) == pytest.approx(-1.0)
    assert sc.enclosed_volume(points, np.empty((0, 3), dtype=np.int64)) == 0.0


def test_distance_to_surface_unsigned_and_signed():
    queries = np.array([[0.5, 0.5, 3.0], [2.0, 2.0, 0.5], [0.5, 0.5, 0.5], [0.5, 0.5, 0.9], [1.0, 0.3, 0.2]])
    expected = np.array([2.0, np.sqrt(2.0), 0.5, 0.1, 0.0])
    assert sc.distance_to_surface(queries, cube()) == pytest.approx(expected, abs=1e-9)
    signed = sc.distance_to_surface(queries, polydata_from_arrays(*cube()), signed=True)
    assert signed[:2] == pytest.approx(expected[:2]) and signed[2:4] == pytest.approx(-expected[2:4])
    assert sc.distance_to_surface(np.empty((0, 3)), cube()).shape == (0,)
    with pytest.raises(ValueError, match="points must have shape"):
        sc.distance_to_surface(np.zeros((2, 2)), cube())
    with pytest.raises(ValueError, match="no triangles"):
        sc.distance_to_surface(queries, (CUBE_POINTS, np.array([[0, 1, 1]])))


def test_hausdorff_between_concentric_cubes_and_spheres():
    small, large = cube(size=1.0), cube(size=1.2)
    distance = sc.hausdorff(small, large)
    # Vertex-sampled: corners of the large cube are 0.1 * sqrt(3) from the small one, corners of the small cube
    # 0.1 from the large one.
    assert distance.a_to_b_max == pytest.approx(0.1) and distance.b_to_a_max == pytest.approx(0.1 * np.sqrt(3))
    assert distance.hausdorff == pytest.approx(0.1 * np.sqrt(3))
    assert distance.mean == pytest.approx((0.1 + 0.1 * np.sqrt(3)) / 2)
    spheres = [marching_cubes(sphere_field((40, 40, 40), r), 0.0) for r in (10.0, 12.0)]
    distance = sc.hausdorff(*spheres)
    assert distance.hausdorff == pytest.approx(2.0, abs=0.1) and distance.mean == pytest.approx(2.0, abs=0.05)
    with pytest.raises(ValueError, match="both surfaces"):
        sc.hausdorff(small, (CUBE_POINTS, np.empty((0, 3), dtype=np.int64)))


def test_distance_to_a_surface_with_collapsed_triangles():
    """Triangles without area (as vtkFlyingEdges3D makes) are left out, not handed to VTK's distance code."""
    points = np.concatenate([CUBE_POINTS, [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]]])  # a duplicate corner, a mid-edge
    triangles = np.concatenate([CUBE_TRIANGLES, [[8, 0, 1], [0, 9, 1]]])  # two collapsed triangles
    queries = np.array([[0.5, 0.5, 2.0], [0.5, -1.0, 0.0]])
    assert sc.distance_to_surface(queries, (points, triangles)) == pytest.approx([1.0, 1.0])


# --------------------------------------------------------------------------------------------------------------
# Topology and orientation
# --------------------------------------------------------------------------------------------------------------
def test_closed_cube_topology():
    report = sc.edge_manifoldness(*cube())
    assert (report.edges, report.boundary_edges, report.nonmanifold_edges) == (18, 0, 0)
    assert report.watertight and report.manifold and report.consistently_oriented
    assert sc.is_watertight(*cube()) and sc.is_manifold(*cube())


def test_holes_flips_fins_and_pinches_are_counted():
    points, triangles = cube()
    report = sc.edge_manifoldness(points, triangles[1:])
    assert report.boundary_edges == 3 and not report.watertight and report.manifold

    flipped = triangles.copy()
    flipped[0] = flipped[0, ::-1]
    report = sc.edge_manifoldness(points, flipped)
    assert report.inconsistent_edges == 3 and report.watertight and not report.consistently_oriented

    fin_points = np.concatenate([points, [[0.5, -1.0, 0.0]]])
    fin = np.concatenate([triangles, [[0, 1, 8]]])  # a third triangle on edge 0-1
    report = sc.edge_manifoldness(fin_points, fin)
    assert report.nonmanifold_edges == 1 and not report.manifold and not sc.is_manifold(fin_points, fin)

    touching = union(cube(), cube(centre=(1.5, 1.5, 1.5)))  # corner (1, 1, 1) twice: points 6 and 8
    merged_points = np.delete(touching[0], 8, axis=0)
    merged = touching[1].copy()
    merged[merged == 8] = 6
    merged[merged > 8] -= 1
    report = sc.edge_manifoldness(merged_points, merged)
    assert report.nonmanifold_vertices == 1 and report.nonmanifold_edges == 0 and report.watertight
    assert not report.manifold
    assert sc.connected_components(merged_points, merged) == 1
    assert sc.connected_components(*touching) == 2
    assert sc.edge_manifoldness(points, np.empty((0, 3), dtype=np.int64)) == sc.EdgeReport(0, 0, 0, 0, 0, 0)


def test_orientation_with_cavities_and_islands():
    outer = cube(size=4.0)
    assert sc.orientation_outward(*outer).outward
    assert not sc.orientation_outward(*cube(size=4.0, inward=True)).outward

    cavity = cube(size=2.0, inward=True)  # a hollow box: the cavity's wall faces into the cavity
    island = cube(size=0.5)  # a solid island in the cavity
    report = sc.orientation_outward(*union(outer, cavity, island))
    assert report.outward and report.components == 3
    assert sorted(report.depth.tolist()) == [0, 1, 2] and report.closed.all()
    assert sorted(report.volumes.tolist()) == pytest.approx([-8.0, 0.125, 64.0])

    wrong = sc.orientation_outward(*union(outer, cube(size=2.0)))  # the cavity wall facing the solid
    assert not wrong.outward

    open_box = (outer[0], outer[1][2:])
    report = sc.orientation_outward(*open_box)
    assert not report.closed[0] and report.outward  # nothing closed to judge


def merged_voxel_surface(mask: np.ndarray):
    """The visible faces of ``mask`` with coincident corners merged (corners lie on an exact lattice)."""
    from algorithms.surfaces.voxel_faces import voxel_faces

    faces = voxel_faces(mask)
    points, inverse = np.unique(faces.points.astype(np.float64), axis=0, return_inverse=True)
    return points, inverse.reshape(-1)[faces.triangles]


def test_ray_crossings_through_edges_and_vertices_are_exact():
    # Rays along +x at (y, z) on voxel corners run exactly through face edges and corners in every slice; the
    # crossing parity must still say inside or outside for every origin off the surface.
    rng = np.random.default_rng(7)
    mask = rng.random((14, 15, 16)) < 0.45  # (z, y, x), many voxels meeting only along edges or at corners
    points, triangles = merged_voxel_surface(mask)
    padded = np.pad(mask, 1)
    origins, expected = [], []
    for k in range(mask.shape[0] + 1):
        for j in range(mask.shape[1] + 1):
            for i in range(mask.shape[2]):
                around = padded[k:k + 2, j:j + 2, i + 1]  # the four voxels around the x-edge through the origin
                if around.all() or not around.any():  # the origin is off the surface
                    origins.append((i + 0.25, j - 0.5, k - 0.5))
                    expected.append(bool(around.all()))
    crossings = sc.ray_crossings(points, triangles, np.array(origins))
    assert len(origins) > 300 and any(expected) and not all(expected)
    assert np.array_equal(crossings % 2 == 1, expected)


def test_ray_crossings_of_a_cube():
    points, triangles = cube()
    origins = [(0.5, 0.5, 0.5), (-1.0, 0.5, 0.5), (2.0, 0.5, 0.5), (0.3, 0.0 + 1e-9, 0.7), (-1.0, 1.0, 1.0)]
    assert sc.ray_crossings(points, triangles, origins).tolist() == [1, 2, 0, 1, 0]
    assert sc.ray_crossings(points, np.empty((0, 3), dtype=np.int64), origins).tolist() == [0] * 5


def test_a_closed_voxel_surface_with_diagonal_contacts_is_watertight_and_outward():
    rng = np.random.default_rng(3)
    mask = rng.random((12, 12, 12)) < 0.5
    mask[4:8, 4:8, 4:8] = False  # a cavity
    mask[5:7, 5:7, 5:7] = True  # with an island in it
    points, triangles = merged_voxel_surface(mask)
    edges = sc.edge_manifoldness(points, triangles)
    assert edges.nonmanifold_edges > 0 and edges.odd_edges == 0
    assert edges.watertight and not edges.manifold and edges.consistently_oriented
    report = sc.orientation_outward(points, triangles)
    assert report.closed.all() and report.outward
    assert report.volumes.sum() == pytest.approx(mask.sum())
    assert not sc.orientation_outward(points, triangles[:, ::-1]).outward
