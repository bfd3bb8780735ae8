"""The mesh types our algorithms return: indexed triangles, triangle strips and tetrahedra.

Every surface method returns one of these (or a small subclass adding what only it knows), so the comparison
toolkit (:mod:`algorithms.compare`) and the application handle them alike:

- :class:`TriangleMesh`: points ``(n, 3)`` and triangles ``(m, 3)``, optional point normals and values
  (marching cubes' :class:`~algorithms.surfaces.marching_cubes.MarchingCubesMesh`, the voxel faces of
  :class:`~algorithms.surfaces.voxel_faces.VoxelFaces`).
- :class:`TriangleStrips`: vertices stored in strip order with CSR ``offsets``, no indices (the tower algorithm's
  :class:`~algorithms.surfaces.tower.TowerStrips`).
- :func:`joined_polydata`: a mesh and strips over one point list (the hybrid surface).
- :class:`TetMesh`: points ``(n, 3)`` and tetrahedra ``(m, 4)`` (tetrahedral meshing).

Coordinates are ``(x, y, z)`` in mm, in the frame of the volume they came from (voxel ``(i, j, k)`` at
``origin + spacing * (i, j, k)``). Orientation follows VTK: a triangle ``(p0, p1, p2)`` faces along
``(p1 - p0) x (p2 - p0)``; in a strip, triangle ``t`` is ``(v_t, v_t+1, v_t+2)`` for even ``t`` and
``(v_t+1, v_t, v_t+2)`` for odd ``t``; a tetrahedron ``(p0, p1, p2, p3)`` has ``p3`` on the side its base
``(p0, p1, p2)`` faces (positive volume, VTK's ``VTK_TETRA`` order).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import VTK_TETRA, vtkPolyData, vtkUnstructuredGrid

from .vtk_bridge import cell_array_from_offsets, vtk_points


def csr_ranks(counts) -> np.ndarray:
    """Position of every item within its group for groups of ``counts`` items stored one after another.

    ``[2, 3] -> [0, 1, 0, 1, 2]``: the rank of an item inside its strip, polygon or fan (int64).
    """
    counts = np.asarray(counts, dtype=np.int64)
    return np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)


def _polydata(points: np.ndarray, *, triangles: np.ndarray | None = None, strips=None) -> vtkPolyData:
    """A ``vtkPolyData`` over ``points`` with ``triangles`` ``(m, 3)`` as polys and ``strips`` (CSR ``offsets``,
    point ids) as strips; deep copies."""
    polydata = vtkPolyData()
    polydata.SetPoints(vtk_points(points))
    if triangles is not None:
        triangles = np.asarray(triangles).reshape(-1, 3)
        polydata.SetPolys(cell_array_from_offsets(np.arange(0, 3 * len(triangles) + 1, 3), triangles.ravel()))
    if strips is not None:
        polydata.SetStrips(cell_array_from_offsets(*strips))
    return polydata


def _point_array(values: np.ndarray, name: str):
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    array.SetName(name)
    return array


@dataclass(frozen=True)
class TriangleMesh:
    """An indexed triangle mesh.

    Attributes
    ----------
    points : ndarray, shape (n, 3), float32
        Vertex positions ``(x, y, z)`` in mm.
    triangles : ndarray, shape (m, 3), int
        Vertex indices of each triangle, counter-clockwise seen from the side it faces.
    normals : ndarray, shape (n, 3), float32, or None
        Unit point normals, if the method computes them.
    values : ndarray, shape (n,), or None
        One value per point (marching cubes: the isovalue of the surface the point belongs to).
    """

    points: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    values: np.ndarray | None = None

    #: Name of the point scalars :meth:`to_polydata` writes ``values`` to, unless it is given another.
    values_name: ClassVar[str] = "values"

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    def to_polydata(self, scalars_name: str | None = None) -> vtkPolyData:
        """The mesh as ``vtkPolyData``: triangles as polys, ``values`` as point scalars (named ``scalars_name``,
        default :attr:`values_name`) and ``normals`` as point normals (``"Normals"``) when present; deep copies."""
        polydata = _polydata(self.points, triangles=self.triangles)
        if self.values is not None:
            polydata.GetPointData().SetScalars(_point_array(self.values, scalars_name or self.values_name))
        if self.normals is not None:
            polydata.GetPointData().SetNormals(_point_array(self.normals, "Normals"))
        return polydata


@dataclass(frozen=True)
class TriangleStrips:
    """Triangle strips whose vertices are stored in strip order, without indices.

    Attributes
    ----------
    points : ndarray, shape (V, 3), float32
        Strip vertices (mm); strip ``s`` is ``points[offsets[s]:offsets[s + 1]]``.
    offsets : ndarray, shape (S + 1,), int64
        CSR offsets of the ``S`` strips into ``points``.
    """

    points: np.ndarray
    offsets: np.ndarray

    @property
    def n_strips(self) -> int:
        return len(self.offsets) - 1

    @property
    def n_vertices(self) -> int:
        return len(self.points)

    @property
    def n_triangles(self) -> int:
        return self.n_vertices - 2 * self.n_strips

    @property
    def lengths(self) -> np.ndarray:
        """Vertices per strip, shape ``(S,)``."""
        return np.diff(self.offsets)

    def to_polydata(self) -> vtkPolyData:
        """The strips as a ``vtkPolyData`` with ``SetStrips`` (point ids ``0 .. V-1`` in order; deep copies)."""
        return _polydata(self.points, strips=(self.offsets, np.arange(self.n_vertices, dtype=np.int64)))


def joined_polydata(mesh: TriangleMesh, strips: TriangleStrips) -> vtkPolyData:
    """Triangles (``SetPolys``) and strips (``SetStrips``) over one point list: the mesh's points first."""
    first = mesh.n_points
    return _polydata(
        np.concatenate([mesh.points, strips.points]),
        triangles=mesh.triangles,
        strips=(strips.offsets, np.arange(first, first + strips.n_vertices, dtype=np.int64)),
    )


@dataclass(frozen=True)
class TetMesh:
    """A tetrahedral mesh.

    Attributes
    ----------
    points : ndarray, shape (n, 3), float64
        Vertex positions ``(x, y, z)`` in mm.
    tetrahedra : ndarray, shape (m, 4), int64
        Vertex indices of each tetrahedron in VTK's ``VTK_TETRA`` order: the base ``(0, 1, 2)`` faces vertex 3,
        so a well-formed tetrahedron has a positive :meth:`volumes`.

    Raises
    ------
    ValueError
        If ``points`` is not ``(n, 3)`` of finite values, or ``tetrahedra`` not ``(m, 4)`` integer indices into it.
    """

    points: np.ndarray
    tetrahedra: np.ndarray

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
            raise ValueError(f"points must be a finite (n, 3) array, got shape {points.shape}")
        tetrahedra = np.asarray(self.tetrahedra)
        if tetrahedra.size == 0:
            tetrahedra = np.empty((0, 4), dtype=np.int64)
        if tetrahedra.ndim != 2 or tetrahedra.shape[1] != 4 or tetrahedra.dtype.kind not in "iu":
            raise ValueError(f"tetrahedra must be integer indices of shape (m, 4), got {tetrahedra.dtype} "
                             f"{tetrahedra.shape}")
        if tetrahedra.size and (tetrahedra.min() < 0 or tetrahedra.max() >= len(points)):
            raise ValueError(f"tetrahedron indices must lie in [0, {len(points)}), got "
                             f"{tetrahedra.min()}..{tetrahedra.max()}")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "tetrahedra", np.ascontiguousarray(tetrahedra, dtype=np.int64))

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_tetrahedra(self) -> int:
        return len(self.tetrahedra)

    def volumes(self) -> np.ndarray:
        """Signed volume of every tetrahedron (mm^3), ``(m,)``: positive in VTK's order."""
        p0, p1, p2, p3 = (self.points[self.tetrahedra[:, c]] for c in range(4))
        return np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), p3 - p0) / 6.0

    def to_unstructured_grid(self, cell_data: dict[str, np.ndarray] | None = None) -> vtkUnstructuredGrid:
        """The mesh as a ``vtkUnstructuredGrid`` of ``VTK_TETRA`` cells (deep copies); ``cell_data`` maps array
        names to one value (or row) per tetrahedron, added as cell arrays (the first one also as active scalars)."""
        grid = vtkUnstructuredGrid()
        grid.SetPoints(vtk_points(self.points))
        cells = cell_array_from_offsets(np.arange(0, 4 * self.n_tetrahedra + 1, 4), self.tetrahedra.ravel())
        grid.SetCells(VTK_TETRA, cells)
        for n, (name, values) in enumerate((cell_data or {}).items()):
            values = np.asarray(values)
            if len(values) != self.n_tetrahedra:
                raise ValueError(f"cell array {name!r} has {len(values)} values for {self.n_tetrahedra} tetrahedra")
            array = _point_array(values, name)
            grid.GetCellData().AddArray(array)
            if n == 0:
                grid.GetCellData().SetActiveScalars(name)
        return grid

    @classmethod
    def from_unstructured_grid(cls, grid) -> "TetMesh":
        """The ``VTK_TETRA`` cells of a ``vtkUnstructuredGrid`` (other cells are left out)."""
        points = numpy_support.vtk_to_numpy(grid.GetPoints().GetData()) if grid.GetPoints() is not None else \
            np.empty((0, 3))
        cells = grid.GetCells()
        if cells is None or grid.GetNumberOfCells() == 0:
            return cls(points, np.empty((0, 4), dtype=np.int64))
        offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
        connectivity = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
        types = numpy_support.vtk_to_numpy(grid.GetCellTypes())
        keep = (types == VTK_TETRA) & (np.diff(offsets) == 4)
        return cls(points, connectivity[offsets[:-1][keep][:, None] + np.arange(4)])
