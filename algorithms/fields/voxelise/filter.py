"""The VTK filter of mesh voxelisation: ``vtkPolyData`` in, a ``vtkImageData`` mask out (see :mod:`.voxelise`).

The output grid is either given (:meth:`VoxeliseFilter.SetGrid`, an :class:`algorithms.common.grid.Grid`) or
taken from a ``vtkImageData`` on the optional second input port (its extent, spacing, origin and direction), like
``vtkPolyDataToImageStencil``'s information input. The mask is ``uint8`` point scalars named ``"mask"`` (1 inside),
placed with the grid's origin and direction matrix, so VTK's filters and the reader of a written file see every
voxel centre where it is.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm, vtkStreamingDemandDrivenPipeline
from vtkmodules.vtkFiltersCore import vtkTriangleFilter

from ...common.grid import Grid
from ...common.vtk_bridge import direction_matrix, polydata_arrays, progress_for, request_data, run_algorithm
from .core import INSIDE_RULES, voxelise_with_report

_SDDP = vtkStreamingDemandDrivenPipeline


def grid_of_image(image: vtkImageData) -> Grid:
    """The :class:`Grid` of an image: its point dimensions, spacing, direction, and the world position of its
    first point (the origin moved to the first index of its extent)."""
    extent = image.GetExtent()
    spacing = np.asarray(image.GetSpacing(), dtype=np.float64)
    direction = direction_matrix(image)
    first = np.asarray(extent[::2], dtype=np.float64)
    origin = np.asarray(image.GetOrigin()) + direction @ (spacing * first)
    dimensions = tuple(int(extent[2 * a + 1] - extent[2 * a] + 1) for a in range(3))
    return Grid(dimensions, tuple(spacing), tuple(origin), tuple(direction.ravel()))


def image_on_grid(mask: np.ndarray, grid: Grid, name: str = "mask") -> vtkImageData:
    """A ``vtkImageData`` holding ``mask`` ``(nz, ny, nx)`` as point scalars on ``grid`` (origin and direction)."""
    image = vtkImageData()
    image.SetDimensions(*grid.dimensions)
    image.SetSpacing(*grid.spacing)
    image.SetOrigin(*grid.origin)
    image.SetDirectionMatrix(*grid.direction)
    scalars = numpy_support.numpy_to_vtk(np.ascontiguousarray(mask).ravel(), deep=True)
    scalars.SetName(name)
    image.GetPointData().SetScalars(scalars)
    return image


class VoxeliseFilter(VTKPythonAlgorithmBase):
    """``vtkPolyData`` (port 0) -> ``vtkImageData`` mask by :func:`~algorithms.fields.voxelise.voxelise`.

    The grid is the image on the optional port 1 when one is connected, else the one given to :meth:`SetGrid`.
    ``SetInside("parity" | "winding")`` chooses the inside rule. Polygons and strips are triangulated first;
    triangles must share the indices of shared points (merge duplicates first, e.g. ``vtkCleanPolyData``).
    Progress and abort work as for VTK's filters; an aborted run returns an empty image (VTK's convention). The
    :class:`~algorithms.fields.voxelise.VoxelisationReport` of the last run is :meth:`GetReport`.

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import run_algorithm
    >>> voxelise = VoxeliseFilter()
    >>> voxelise.SetInputDataObject(0, mesh)
    >>> voxelise.SetInputDataObject(1, ct_image)   # or voxelise.SetGrid(Grid.around(mesh.GetBounds(), voxels=256))
    >>> mask = run_algorithm(voxelise)
    """

    def __init__(self) -> None:
        super().__init__(nInputPorts=2, nOutputPorts=1, outputType="vtkImageData")
        self._grid: Grid | None = None
        self._inside = "parity"
        self._report = None

    def FillInputPortInformation(self, port, info):  # noqa: N802
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkPolyData" if port == 0 else "vtkImageData")
        if port == 1:
            info.Set(vtkAlgorithm.INPUT_IS_OPTIONAL(), 1)
        return 1

    # -- options ----------------------------------------------------------------------------------------------
    def SetGrid(self, grid: Grid | None) -> None:  # noqa: N802
        if grid is not None and not isinstance(grid, Grid):
            raise ValueError(f"the grid must be an algorithms.common.grid.Grid, got {type(grid).__name__}")
        if grid != self._grid:
            self._grid = grid
            self.Modified()

    def GetGrid(self) -> Grid | None:  # noqa: N802
        return self._grid

    def SetInside(self, rule: str) -> None:  # noqa: N802
        if rule not in INSIDE_RULES:
            raise ValueError(f"the inside rule is one of {', '.join(INSIDE_RULES)}, got {rule!r}")
        if rule != self._inside:
            self._inside = rule
            self.Modified()

    def GetInside(self) -> str:  # noqa: N802
        return self._inside

    def GetReport(self):  # noqa: N802
        return self._report

    # -- pipeline -----------------------------------------------------------------------------------------------
    def _reference(self, in_info):
        if self.GetNumberOfInputConnections(1) == 0:
            return None
        return in_info[1].GetInformationObject(0)

    def _output_grid(self, in_info) -> Grid | None:
        reference = self._reference(in_info)
        if reference is not None:
            image = vtkImageData.GetData(reference)
            if image is not None and image.GetNumberOfPoints() > 0:
                return grid_of_image(image)
        return self._grid

    def RequestInformation(self, request, in_info, out_info):  # noqa: N802
        info = out_info.GetInformationObject(0)
        reference = self._reference(in_info)
        if reference is not None:
            extent = reference.Get(_SDDP.WHOLE_EXTENT())
            if extent is not None:
                info.Set(_SDDP.WHOLE_EXTENT(), tuple(extent), 6)
            return 1
        if self._grid is not None:
            nx, ny, nz = self._grid.dimensions
            info.Set(_SDDP.WHOLE_EXTENT(), (0, nx - 1, 0, ny - 1, 0, nz - 1), 6)
        return 1

    def RequestUpdateExtent(self, request, in_info, out_info):  # noqa: N802
        reference = self._reference(in_info)
        if reference is not None:  # the whole reference image defines the grid
            reference.Set(_SDDP.UPDATE_EXTENT(), reference.Get(_SDDP.WHOLE_EXTENT()), 6)
        return 1

    @request_data
    def RequestData(self, request, in_info, out_info):  # noqa: N802
        mesh = vtkPolyData.GetData(in_info[0], 0)
        output = vtkImageData.GetData(out_info, 0)
        grid = self._output_grid(in_info)
        if grid is None:
            raise ValueError("VoxeliseFilter needs a grid: connect an image to port 1 or call SetGrid")
        points, triangles = _triangles_of(mesh)
        mask, self._report = voxelise_with_report(points, triangles, grid, inside=self._inside,
                                                  progress=progress_for(self))
        output.ShallowCopy(image_on_grid(mask, grid))
        return 1


def _triangles_of(mesh: vtkPolyData) -> tuple[np.ndarray, np.ndarray]:
    """Points and triangles of ``mesh``, triangulating polygons and strips when there are any."""
    if mesh is None or mesh.GetNumberOfPoints() == 0:
        return np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
    if mesh.GetNumberOfStrips() == 0:
        try:
            return polydata_arrays(mesh)
        except ValueError:  # polygons other than triangles
            pass
    triangulate = vtkTriangleFilter()
    triangulate.SetInputData(mesh)
    triangulate.PassVertsOff()
    triangulate.PassLinesOff()
    return polydata_arrays(run_algorithm(triangulate))
