"""The VTK filters of signed distance fields and CSG: ``DistanceFieldFilter`` (``vtkPolyData`` -> ``vtkImageData``
of float32 mm, negative inside; :func:`.core.signed_distance`) and ``CsgFilter`` (two or more images of
distance fields on one grid -> their union, intersection or difference; :func:`.csg.combine`).

Grids as in :mod:`algorithms.fields.voxelise.filter`: given with ``SetGrid`` or taken from an image on the optional second port;
images carry their origin and direction matrix. Arrays ``(nz, ny, nx)``; mm.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from ...common.grid import Grid
from ...common.vtk_bridge import array_from_image, progress_for, request_data
from ..csg import OPERATIONS, combine
from ..voxelise.filter import _triangles_of, grid_of_image, image_on_grid
from .core import OUTSIDE_RULES, signed_distance


class DistanceFieldFilter(VTKPythonAlgorithmBase):
    """``vtkPolyData`` (port 0) -> ``vtkImageData`` with point scalars ``"distance"`` (float32 mm, negative inside).

    ``SetGrid(Grid)`` or an image on port 1 gives the grid; ``SetBand(mm)``, ``SetOutside("clamp" | "propagate")``,
    ``SetInside("parity" | "winding")``. :meth:`GetResult` is the last :class:`~.core.DistanceField` (nearest
    triangles and seconds). Progress and abort as VTK's filters.
    """

    def __init__(self) -> None:
        super().__init__(nInputPorts=2, nOutputPorts=1, outputType="vtkImageData")
        self._grid: Grid | None = None
        self._band = 1.0
        self._outside = "clamp"
        self._inside = "parity"
        self._result = None

    def FillInputPortInformation(self, port, info):  # noqa: N802
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkPolyData" if port == 0 else "vtkImageData")
        if port == 1:
            info.Set(vtkAlgorithm.INPUT_IS_OPTIONAL(), 1)
        return 1

    def _set(self, name, value):
        if getattr(self, name) != value:
            setattr(self, name, value)
            self.Modified()

    def SetGrid(self, grid: Grid | None) -> None:  # noqa: N802
        if grid is not None and not isinstance(grid, Grid):
            raise ValueError(f"the grid must be an algorithms.common.grid.Grid, got {type(grid).__name__}")
        self._set("_grid", grid)

    def SetBand(self, band_mm: float) -> None:  # noqa: N802
        if not float(band_mm) > 0:
            raise ValueError(f"the band width must be a positive number of mm, got {band_mm}")
        self._set("_band", float(band_mm))

    def SetOutside(self, rule: str) -> None:  # noqa: N802
        if rule not in OUTSIDE_RULES:
            raise ValueError(f"outside must be one of {', '.join(OUTSIDE_RULES)}, got {rule!r}")
        self._set("_outside", rule)

    def SetInside(self, rule: str) -> None:  # noqa: N802
        self._set("_inside", rule)

    def GetResult(self):  # noqa: N802
        return self._result

    @request_data
    def RequestData(self, request, in_info, out_info):  # noqa: N802
        mesh = vtkPolyData.GetData(in_info[0], 0)
        output = vtkImageData.GetData(out_info, 0)
        grid = self._grid
        if self.GetNumberOfInputConnections(1):
            image = vtkImageData.GetData(in_info[1], 0)
            if image is not None and image.GetNumberOfPoints() > 0:
                grid = grid_of_image(image)
        if grid is None:
            raise ValueError("DistanceFieldFilter needs a grid: connect an image to port 1 or call SetGrid")
        points, triangles = _triangles_of(mesh)
        self._result = signed_distance(points, triangles, grid, band_mm=self._band, outside=self._outside,
                                       inside=self._inside, progress=progress_for(self))
        output.ShallowCopy(image_on_grid(self._result.values, grid, "distance"))
        return 1


class CsgFilter(VTKPythonAlgorithmBase):
    """Two or more ``vtkImageData`` distance fields on one grid (all connections of port 0) -> their union,
    intersection or difference (``SetOperation``), smooth with ``SetBlend(mm)`` > 0; point scalars ``"distance"``.
    Images on different grids are refused (resample them first, e.g. ``app.volume.Volume.resampled``)."""

    def __init__(self) -> None:
        super().__init__(nInputPorts=1, nOutputPorts=1, inputType="vtkImageData", outputType="vtkImageData")
        self._operation = "union"
        self._blend = 0.0

    def FillInputPortInformation(self, port, info):  # noqa: N802
        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(), "vtkImageData")
        info.Set(vtkAlgorithm.INPUT_IS_REPEATABLE(), 1)
        return 1

    def SetOperation(self, operation: str) -> None:  # noqa: N802
        if operation not in OPERATIONS:
            raise ValueError(f"operation must be one of {', '.join(OPERATIONS)}, got {operation!r}")
        if operation != self._operation:
            self._operation = operation
            self.Modified()

    def SetBlend(self, blend_mm: float) -> None:  # noqa: N802
        if not float(blend_mm) >= 0:
            raise ValueError(f"the blend radius must be 0 or a positive number of mm, got {blend_mm}")
        if float(blend_mm) != self._blend:
            self._blend = float(blend_mm)
            self.Modified()

    @request_data
    def RequestData(self, request, in_info, out_info):  # noqa: N802
        images = [vtkImageData.GetData(in_info[0], c) for c in range(self.GetNumberOfInputConnections(0))]
        output = vtkImageData.GetData(out_info, 0)
        grids = [grid_of_image(image) for image in images]
        for n, grid in enumerate(grids[1:], start=2):
            if not grid.same_as(grids[0]):
                raise ValueError(f"field {n} is on another grid than field 1; resample them onto one grid first")
        fields = [np.asarray(array_from_image(image), np.float32) for image in images]
        values = combine(fields, self._operation, blend_mm=self._blend)
        output.ShallowCopy(image_on_grid(values, grids[0], "distance"))
        return 1
