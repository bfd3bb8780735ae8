"""The VTK filter of marching cubes: ``vtkImageData`` in, ``vtkPolyData`` isosurfaces out, with
``vtkMarchingCubes``' API (contour values in a ``vtkContourValues``, normals, a preview stride)."""

from __future__ import annotations

import weakref

import numpy as np
from vtkmodules.util.numpy_support import get_vtk_array_type, numpy_to_vtk
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkCommand, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkImageData, vtkPolyData
from vtkmodules.vtkCommonMisc import vtkContourValues

from ...common.validation import validated_count
from ...common.vtk_bridge import array_from_image, direction_matrix, progress_for, request_data
from .core import MarchingCubesMesh, marching_cubes


def _modified_on_change(algorithm: VTKPythonAlgorithmBase, member) -> None:
    """Mark ``algorithm`` modified whenever ``member`` is.

    VTK's contour filters override ``GetMTime`` in C++ to include their ``vtkContourValues``; a Python override
    (which :class:`MarchingCubesFilter` also has) is not seen by the pipeline's executive, which calls the C++
    method, so the change is forwarded as a ``Modified()`` of the filter. The observer holds the filter weakly.
    """
    owner = weakref.ref(algorithm)

    def forward(caller, event):
        target = owner()
        if target is not None:
            target.Modified()

    member.AddObserver(vtkCommand.ModifiedEvent, forward)


class MarchingCubesFilter(VTKPythonAlgorithmBase):
    """``vtkImageData`` -> ``vtkPolyData`` isosurfaces by :func:`marching_cubes`, with ``vtkMarchingCubes``' API.

    Contour values live in a ``vtkContourValues`` (:meth:`GetContourValues`), as in VTK's contour filters:
    ``SetValue(i, value)``, ``GetValue``, ``GetValues``, ``SetNumberOfContours(n)``, ``GetNumberOfContours`` and
    ``GenerateValues(n, low, high)`` delegate to it (one contour at 0.0 to start with; values added by ``SetValue``
    beyond the end, or by ``SetNumberOfContours``, start at 0.0). The values must be distinct when the filter runs.
    ``GetMTime`` is the later of the filter's and the contour values' modification times, and a change of the
    contour values also modifies the filter, so the pipeline runs again. ``ComputeNormals`` is on by default, as
    in VTK. ``SetStride`` extracts a preview from every ``stride``-th sample. The input's active point scalars are
    contoured; the output is placed like VTK's: index ``(i, j, k)`` of the input extent at
    ``origin + direction @ (spacing * index)``. Output point data: the isovalue of each point as scalars (named
    after the input array) and, if computed, ``Normals``. Errors (e.g. equal contour values) are VTK error events;
    an aborted run returns an empty output (VTK's convention).

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    >>> contour = MarchingCubesFilter()
    >>> contour.SetInputDataObject(image_from_array(volume, spacing, origin))
    >>> contour.SetValue(0, 300.0)
    >>> polydata = run_algorithm(contour)
    """

    def __init__(self) -> None:
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkPolyData")
        self._contours = vtkContourValues()  # one contour at 0.0
        _modified_on_change(self, self._contours)
        self._compute_normals = True
        self._stride = 1

    # -- contour values (delegated to vtkContourValues) ---------------------------------------------------------
    def GetContourValues(self) -> vtkContourValues:  # noqa: N802 - VTK naming
        return self._contours

    def SetValue(self, index: int, value: float) -> None:  # noqa: N802
        index, value = int(index), float(value)
        if index < 0:
            raise ValueError(f"contour index must be 0 or more, got {index}")
        if index >= self._contours.GetNumberOfContours():
            self._contours.SetNumberOfContours(index + 1)  # new entries 0.0 (SetValue alone leaves them undefined)
        self._contours.SetValue(index, value)

    def GetValue(self, index: int) -> float:  # noqa: N802
        index = int(index)
        if not 0 <= index < self._contours.GetNumberOfContours():
            raise IndexError(f"contour index {index} out of range (0 to {self._contours.GetNumberOfContours() - 1})")
        return self._contours.GetValue(index)

    def GetValues(self) -> tuple[float, ...]:  # noqa: N802
        return tuple(self._contours.GetValue(i) for i in range(self._contours.GetNumberOfContours()))

    def SetNumberOfContours(self, count: int) -> None:  # noqa: N802
        count = int(count)
        if count < 0:
            raise ValueError(f"the number of contours must be 0 or more, got {count}")
        self._contours.SetNumberOfContours(count)

    def GetNumberOfContours(self) -> int:  # noqa: N802
        return self._contours.GetNumberOfContours()

    def GenerateValues(self, count: int, low: float, high: float) -> None:  # noqa: N802
        """``count`` contour values evenly from ``low`` to ``high`` inclusive (``vtkContourValues.GenerateValues``)."""
        self._contours.GenerateValues(int(count), float(low), float(high))

    def GetMTime(self) -> int:  # noqa: N802
        return max(super().GetMTime(), self._contours.GetMTime())

    # -- other options ------------------------------------------------------------------------------------------
    def SetComputeNormals(self, flag: bool) -> None:  # noqa: N802
        flag = bool(flag)
        if flag != self._compute_normals:
            self._compute_normals = flag
            self.Modified()

    def GetComputeNormals(self) -> bool:  # noqa: N802
        return self._compute_normals

    def ComputeNormalsOn(self) -> None:  # noqa: N802
        self.SetComputeNormals(True)

    def ComputeNormalsOff(self) -> None:  # noqa: N802
        self.SetComputeNormals(False)

    def SetStride(self, stride: int) -> None:  # noqa: N802
        """Extract from every ``stride``-th sample along each axis (1: full resolution; 2 or 4: a preview)."""
        stride = validated_count(stride, "stride")
        if stride != self._stride:
            self._stride = stride
            self.Modified()

    def GetStride(self) -> int:  # noqa: N802
        return self._stride

    # -- pipeline -----------------------------------------------------------------------------------------------
    @request_data
    def RequestData(self, request, in_info, out_info):  # noqa: N802
        image = vtkImageData.GetData(in_info[0], 0)
        output = vtkPolyData.GetData(out_info, 0)
        values = self.GetValues()
        if not values:
            return 1
        spacing = np.array(image.GetSpacing())
        first_index = np.array(image.GetExtent()[::2], dtype=np.float64)
        direction = direction_matrix(image)
        mesh = marching_cubes(
            array_from_image(image),
            values,
            spacing=spacing,
            origin=spacing * first_index,
            stride=self._stride,
            normals=self._compute_normals,
            progress=progress_for(self),
        )
        if not np.allclose(direction, np.eye(3)):
            mesh = MarchingCubesMesh(
                points=(mesh.points @ direction.T).astype(np.float32),
                triangles=mesh.triangles,
                normals=None if mesh.normals is None else (mesh.normals @ direction.T).astype(np.float32),
                values=mesh.values,
            )
        name = image.GetPointData().GetScalars().GetName() or "Isovalue"
        mesh.points[...] += np.asarray(image.GetOrigin(), dtype=mesh.points.dtype)
        output.ShallowCopy(_shared_polydata(mesh, name))
        return 1


def _shared(array: np.ndarray, name: str | None = None, array_type: int | None = None):
    """A VTK array on the memory of a contiguous NumPy array (kept alive by the VTK array)."""
    vtk_array = numpy_to_vtk(np.ascontiguousarray(array), deep=False, array_type=array_type)
    if name:
        vtk_array.SetName(name)
    return vtk_array


def _shared_polydata(mesh: MarchingCubesMesh, scalars_name: str) -> vtkPolyData:
    """The mesh as ``vtkPolyData`` without copying its points, triangles, normals or values (a large mesh is not
    held twice): ``Points``, triangles as polys, the isovalues as point scalars named ``scalars_name``, and
    ``Normals`` when computed."""
    polydata = vtkPolyData()
    points = vtkPoints()
    points.SetData(_shared(mesh.points.reshape(-1, 3)))
    polydata.SetPoints(points)
    id_type = get_vtk_array_type(np.int64)
    cells = vtkCellArray()
    offsets = np.arange(0, 3 * mesh.triangles.shape[0] + 1, 3, dtype=np.int64)
    cells.SetData(_shared(offsets, array_type=id_type), _shared(mesh.triangles.reshape(-1), array_type=id_type))
    polydata.SetPolys(cells)
    polydata.GetPointData().SetScalars(_shared(mesh.values, scalars_name))
    if mesh.normals is not None:
        polydata.GetPointData().SetNormals(_shared(mesh.normals, "Normals"))
    return polydata
