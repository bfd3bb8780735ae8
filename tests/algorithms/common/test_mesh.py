"""The shared mesh types: triangle meshes, triangle strips, both over one point list, tetrahedral meshes."""

from __future__ import annotations

import numpy as np
import pytest
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import VTK_TETRA
from vtkmodules.vtkFiltersVerdict import vtkCellSizeFilter

from algorithms.common.mesh import TetMesh, TriangleMesh, TriangleStrips, csr_ranks, joined_polydata
from algorithms.common.vtk_bridge import cell_arrays, polydata_arrays, run_algorithm
from algorithms.compare.voxel_surfaces import strip_triangles

#: A unit cube's corners and its 12 outward triangles.
CUBE_POINTS = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float32)
CUBE_TRIANGLES = np.array([
    [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
    [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5],
], dtype=np.int64)


def test_csr_ranks():
    assert csr_ranks([2, 3]).tolist() == [0, 1, 0, 1, 2]
    assert csr_ranks([0, 1, 0, 2]).tolist() == [0, 0, 1]
    assert csr_ranks(np.empty(0, dtype=np.int64)).size == 0


def test_triangle_mesh_round_trip():
    normals = (CUBE_POINTS - 0.5) / np.linalg.norm(CUBE_POINTS - 0.5, axis=1, keepdims=True)
    values = np.arange(8, dtype=np.float32)
    mesh = TriangleMesh(CUBE_POINTS, CUBE_TRIANGLES, normals.astype(np.float32), values)
    assert (mesh.n_points, mesh.n_triangles) == (8, 12)
    polydata = mesh.to_polydata()
    points, triangles = polydata_arrays(polydata)
    assert points.dtype == np.float32
    np.testing.assert_array_equal(points, CUBE_POINTS)
    np.testing.assert_array_equal(triangles, CUBE_TRIANGLES)
    scalars = polydata.GetPointData().GetScalars()
    assert scalars.GetName() == "values"
    np.testing.assert_array_equal(numpy_support.vtk_to_numpy(scalars), values)
    np.testing.assert_array_equal(numpy_support.vtk_to_numpy(polydata.GetPointData().GetNormals()), normals)
    assert polydata.GetPointData().GetNormals().GetName() == "Normals"
    assert mesh.to_polydata(scalars_name="density").GetPointData().GetScalars().GetName() == "density"
    # Deep copies: changing the mesh afterwards does not change the polydata.
    points_copy = np.array(CUBE_POINTS)
    copied = TriangleMesh(points_copy, CUBE_TRIANGLES).to_polydata()
    points_copy[:] = 7.0
    assert polydata_arrays(copied)[0].max() == 1.0


def test_triangle_mesh_without_attributes():
    polydata = TriangleMesh(CUBE_POINTS, CUBE_TRIANGLES.astype(np.int32)).to_polydata()
    assert polydata.GetPointData().GetScalars() is None and polydata.GetPointData().GetNormals() is None
    assert polydata.GetNumberOfPolys() == 12 and polydata.GetNumberOfStrips() == 0
    empty = TriangleMesh(np.empty((0, 3), np.float32), np.empty((0, 3), np.int64)).to_polydata()
    assert empty.GetNumberOfPoints() == 0 and empty.GetNumberOfCells() == 0


def test_triangle_strips_round_trip():
    # Two strips over a zig-zag of points: 4 vertices (2 triangles) and 5 vertices (3 triangles).
    points = np.random.default_rng(1).random((9, 3)).astype(np.float32)
    strips = TriangleStrips(points, np.array([0, 4, 9]))
    assert (strips.n_strips, strips.n_vertices, strips.n_triangles) == (2, 9, 5)
    assert strips.lengths.tolist() == [4, 5]
    polydata = strips.to_polydata()
    assert polydata.GetNumberOfStrips() == 2 and polydata.GetNumberOfPolys() == 0
    np.testing.assert_array_equal(numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()), points)
    offsets, connectivity = cell_arrays(polydata.GetStrips())
    assert offsets.tolist() == [0, 4, 9] and connectivity.tolist() == list(range(9))
    # VTK's alternating winding: odd triangles swap their first two vertices.
    assert strip_triangles(offsets, connectivity).tolist() == [[0, 1, 2], [2, 1, 3], [4, 5, 6], [6, 5, 7], [6, 7, 8]]


def test_joined_polydata_puts_the_mesh_points_first():
    mesh = TriangleMesh(CUBE_POINTS, CUBE_TRIANGLES)
    strips = TriangleStrips(CUBE_POINTS[[0, 1, 2, 3]] + 5.0, np.array([0, 4]))
    polydata = joined_polydata(mesh, strips)
    assert polydata.GetNumberOfPoints() == 12
    assert (polydata.GetNumberOfPolys(), polydata.GetNumberOfStrips()) == (12, 1)
    points = numpy_support.vtk_to_numpy(polydata.GetPoints().GetData())
    np.testing.assert_array_equal(points[:8], CUBE_POINTS)
    np.testing.assert_array_equal(points[8:], strips.points)
    assert cell_arrays(polydata.GetStrips())[1].tolist() == [8, 9, 10, 11]
    assert cell_arrays(polydata.GetPolys())[1].reshape(-1, 3).tolist() == CUBE_TRIANGLES.tolist()


def test_tet_mesh_to_unstructured_grid():
    # The unit cube split into five tetrahedra (one central, four corners), all in VTK's positive order.
    tetrahedra = np.array([[0, 3, 5, 6], [0, 1, 3, 5], [0, 2, 6, 3], [0, 4, 5, 6], [3, 5, 6, 7]])
    tetrahedra = np.where((TetMesh(CUBE_POINTS, tetrahedra).volumes() < 0)[:, None], tetrahedra[:, [1, 0, 2, 3]],
                          tetrahedra)
    mesh = TetMesh(CUBE_POINTS, tetrahedra)
    assert mesh.points.dtype == np.float64 and mesh.tetrahedra.dtype == np.int64
    assert (mesh.n_points, mesh.n_tetrahedra) == (8, 5)
    np.testing.assert_allclose(np.sort(mesh.volumes()), [1 / 6] * 4 + [1 / 3])
    assert mesh.volumes().sum() == pytest.approx(1.0)
    grid = mesh.to_unstructured_grid()
    assert grid.GetNumberOfPoints() == 8 and grid.GetNumberOfCells() == 5
    assert {grid.GetCellType(c) for c in range(5)} == {VTK_TETRA}
    np.testing.assert_array_equal(numpy_support.vtk_to_numpy(grid.GetPoints().GetData()), CUBE_POINTS)
    offsets, connectivity = cell_arrays(grid.GetCells())
    assert offsets.tolist() == [0, 4, 8, 12, 16, 20]
    assert connectivity.reshape(-1, 4).tolist() == tetrahedra.tolist()
    # VTK measures the same (unsigned) volumes.
    sizes = vtkCellSizeFilter()
    sizes.SetInputData(grid)
    measured = numpy_support.vtk_to_numpy(run_algorithm(sizes).GetCellData().GetArray("Volume"))
    np.testing.assert_allclose(measured, mesh.volumes(), atol=1e-12)


def test_tet_mesh_rejects_malformed_arrays():
    points = np.zeros((4, 3))
    assert TetMesh(points, np.empty(0)).n_tetrahedra == 0
    with pytest.raises(ValueError, match=r"points must be a finite \(n, 3\) array"):
        TetMesh(np.zeros((4, 2)), [[0, 1, 2, 3]])
    with pytest.raises(ValueError, match=r"points must be a finite \(n, 3\) array"):
        TetMesh(np.full((4, 3), np.nan), [[0, 1, 2, 3]])
    with pytest.raises(ValueError, match=r"tetrahedra must be integer indices of shape \(m, 4\)"):
        TetMesh(points, [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"tetrahedra must be integer indices of shape \(m, 4\)"):
        TetMesh(points, [[0.0, 1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match=r"tetrahedron indices must lie in \[0, 4\)"):
        TetMesh(points, [[0, 1, 2, 4]])
