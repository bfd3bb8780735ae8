"""The VTK filter of isosurface stuffing: ``vtkImageData`` in, ``vtkUnstructuredGrid`` of tetrahedra out (volume
frame, the image's origin and direction applied), with the cell array ``min_dihedral_deg``."""

from __future__ import annotations

import numpy as np
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkUnstructuredGrid

from ...common.mesh import TetMesh
from ...common.vtk_bridge import array_from_image, direction_matrix, progress_for, request_data
from .core import isosurface_stuffing, resolve_alphas


class IsosurfaceStuffingFilter(VTKPythonAlgorithmBase):
    """``vtkImageData`` -> tetrahedra filling ``value >= isovalue`` by :func:`isosurface_stuffing`.

    ``SetIsovalue``, ``SetLatticeSpacing`` (h, mm), ``SetAlpha`` ("10.7" or "8.9"). Errors are VTK error events;
    an aborted run returns an empty output (VTK's convention).
    """

    def __init__(self) -> None:
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkUnstructuredGrid")
        self._iso = 0.0
        self._h = 1.0
        self._alpha = "10.7"

    def _set(self, name: str, value) -> None:
        if getattr(self, name) != value:
            setattr(self, name, value)
            self.Modified()

    def SetIsovalue(self, value: float) -> None:  # noqa: N802 - VTK naming
        self._set("_iso", float(value))

    def GetIsovalue(self) -> float:  # noqa: N802
        return self._iso

    def SetLatticeSpacing(self, h: float) -> None:  # noqa: N802
        if not float(h) > 0:
            raise ValueError(f"the lattice spacing must be a positive number of mm, got {h}")
        self._set("_h", float(h))

    def GetLatticeSpacing(self) -> float:  # noqa: N802
        return self._h

    def SetAlpha(self, alpha) -> None:  # noqa: N802
        self._set("_alpha", resolve_alphas(alpha)[0])

    def GetAlpha(self) -> str:  # noqa: N802
        return self._alpha

    @request_data
    def RequestData(self, request, in_info, out_info):  # noqa: N802
        from algorithms.compare.tet_quality import min_max_dihedral

        image = vtkImageData.GetData(in_info[0], 0)
        output = vtkUnstructuredGrid.GetData(out_info, 0)
        spacing = np.array(image.GetSpacing())
        first_index = np.array(image.GetExtent()[::2], dtype=np.float64)
        result = isosurface_stuffing(array_from_image(image), self._iso, h=self._h, spacing=spacing,
                                     origin=spacing * first_index, alpha=self._alpha,
                                     progress=progress_for(self))
        direction = direction_matrix(image)
        points = result.mesh.points @ direction.T + np.asarray(image.GetOrigin())
        tets = result.mesh.tetrahedra if np.linalg.det(direction) > 0 else result.mesh.tetrahedra[:, [1, 0, 2, 3]]
        mesh = TetMesh(points, tets)
        smallest, _ = min_max_dihedral(mesh.points, mesh.tetrahedra)
        output.ShallowCopy(mesh.to_unstructured_grid(cell_data={"min_dihedral_deg": smallest}))
        return 1
