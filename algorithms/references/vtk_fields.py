"""VTK's built-ins for fields from meshes, run the way we run our own filters (:func:`run_algorithm`).

- :func:`vtk_stencil_mask`: mesh voxelisation by ``vtkPolyDataToImageStencil`` + ``vtkImageStencilToImage``, the
  reference of :func:`algorithms.fields.voxelise.voxelise` (source 002, section 2.2).

``vtkPolyDataToImageStencil`` cuts the mesh with the plane of each slice (its own cutter), joins the cut segments
into contours and fills them row by row; it has no direction matrix, so for a rotated grid the mesh is moved into
the grid's own frame (axes along the grid's, origin at the grid's first voxel) and the stencil is made there,
which puts every voxel centre where the grid has it. Its ``Tolerance`` (default 1e-3 of a voxel) widens the stencil
by that much; :func:`vtk_stencil_mask` sets it to 0 unless told otherwise, so a centre is inside exactly when it is
inside the mesh.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkImagingStencil import vtkImageStencilToImage, vtkPolyDataToImageStencil

from ..common.grid import Grid
from ..common.progress import ProgressCallback
from ..common.vtk_bridge import polydata_from_arrays, polydata_arrays, run_algorithm

__all__ = ["StencilPipeline", "vtk_stencil_mask"]


class StencilPipeline:
    """``vtkPolyDataToImageStencil`` -> ``vtkImageStencilToImage`` set up for one mesh and grid, to run repeatedly
    (the benchmarks time :meth:`run` alone; the mesh was moved into the grid's frame once, here).

    Parameters are those of :func:`vtk_stencil_mask`.
    """

    def __init__(self, mesh, grid: Grid, *, tolerance: float = 0.0) -> None:
        if not isinstance(grid, Grid):
            raise ValueError(f"grid must be an algorithms.common.grid.Grid, got {type(grid).__name__}")
        if isinstance(mesh, vtkPolyData):
            points, triangles = polydata_arrays(mesh)
        else:
            points, triangles = mesh
        points = np.asarray(points, dtype=np.float64)
        local = (points - np.asarray(grid.origin)) @ grid.direction_matrix  # the grid's frame, mm
        self.polydata = polydata_from_arrays(local, np.asarray(triangles, dtype=np.int64))
        self.grid = grid
        nx, ny, nz = grid.dimensions
        self.stencil = vtkPolyDataToImageStencil()
        self.stencil.SetInputData(self.polydata)
        self.stencil.SetOutputSpacing(*grid.spacing)
        self.stencil.SetOutputOrigin(0.0, 0.0, 0.0)
        self.stencil.SetOutputWholeExtent(0, nx - 1, 0, ny - 1, 0, nz - 1)
        self.stencil.SetTolerance(float(tolerance))
        self.to_image = vtkImageStencilToImage()
        self.to_image.SetInputConnection(self.stencil.GetOutputPort())
        self.to_image.SetInsideValue(1)
        self.to_image.SetOutsideValue(0)
        self.to_image.SetOutputScalarTypeToUnsignedChar()

    def run(self, progress: ProgressCallback = None) -> np.ndarray:
        """Run both filters again; the mask ``(nz, ny, nx)`` uint8 as a view of VTK's output."""
        self.stencil.Modified()
        image = run_algorithm(self.to_image, progress)
        nx, ny, nz = self.grid.dimensions
        return numpy_support.vtk_to_numpy(image.GetPointData().GetScalars()).reshape(nz, ny, nx)


def vtk_stencil_mask(mesh, grid: Grid, *, tolerance: float = 0.0, progress: ProgressCallback = None) -> np.ndarray:
    """The mask ``(nz, ny, nx)`` uint8 (1 inside) of a closed mesh on ``grid`` by VTK's image stencil.

    Parameters
    ----------
    mesh : vtkPolyData or (points, triangles)
        The surface in LPS mm (triangles).
    grid : Grid
        Target grid; rotated grids are handled by moving the mesh into the grid's frame.
    tolerance : float
        ``vtkPolyDataToImageStencil.SetTolerance`` (fraction of a voxel; VTK's default is 1e-3).
    progress : callable, optional
        VTK's progress of the stencil-to-image filter; may raise ``OperationCancelled``.

    Notes
    -----
    Where the mesh leaves the grid, VTK's stencil can fill rows wrongly (it clips the slice contours at the grid's
    edge); compare on grids that hold the whole mesh.
    """
    return np.array(StencilPipeline(mesh, grid, tolerance=tolerance).run(progress), dtype=np.uint8)
