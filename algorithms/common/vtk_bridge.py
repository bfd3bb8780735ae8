"""The bridge between NumPy and VTK: running algorithms, and converting images, meshes and matrices.

Shared by our filters and by the code that runs VTK's built-ins (:mod:`algorithms.references`).

Array axis order used everywhere in Voxelscope
----------------------------------------------
A volume's NumPy array has shape ``(nz, ny, nx)`` and is indexed ``array[k, j, i]``; ``i`` varies fastest in
memory (C order). VTK stores image points with x varying fastest, so ``array.ravel()`` (C order) is exactly VTK's
point order and ``vtkImageData.GetDimensions()`` is ``(nx, ny, nz)``. Spacing and origin tuples are always given
in VTK order ``(x, y, z)``.
"""

from __future__ import annotations

import functools

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkCommand, vtkObject
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from .progress import OperationCancelled, ProgressCallback


class VTKError(RuntimeError):
    """A VTK algorithm reported an error while it ran."""


def clean_vtk_message(message) -> str:
    """The human part of a VTK error message, without the "ERROR: In file.cxx, line N" and object address."""
    if message is None:
        return ""
    lines = [line.strip() for line in str(message).splitlines() if line.strip()]
    lines = [line for line in lines if not line.startswith(("ERROR: In ", "Warning: In ", "WARNING: In "))]
    text = " ".join(lines)
    # "vtkXMLImageDataReader (0x55d...): Error opening file x" -> "Error opening file x"
    if "): " in text and text.split("): ", 1)[0].count("(0x") == 1:
        text = text.split("): ", 1)[1]
    return text


class _ErrorObserver:
    """Collects the ErrorEvent/WarningEvent messages a VTK object emits."""

    def __init__(self) -> None:
        self.errors: list[str] = []
        self.warnings: list[str] = []

    def attach(self, obj: vtkObject) -> list[int]:
        def on_error(caller, event, message=None):
            self.errors.append(clean_vtk_message(message) or f"{caller.GetClassName()} failed")

        def on_warning(caller, event, message=None):
            self.warnings.append(clean_vtk_message(message))

        # Python observers receive the message string as call data when this attribute is set.
        on_error.CallDataType = "string0"
        on_warning.CallDataType = "string0"
        return [obj.AddObserver(vtkCommand.ErrorEvent, on_error), obj.AddObserver(vtkCommand.WarningEvent, on_warning)]


def run_algorithm(algorithm: vtkAlgorithm, progress: ProgressCallback = None, port: int = 0):
    """Update ``algorithm`` and return its output data object.

    Runs our Python filters and VTK's built-ins the same way: VTK progress events are forwarded to ``progress``
    (which may raise :class:`OperationCancelled`; the algorithm is then asked to abort), and VTK error output is
    turned into a :class:`VTKError` instead of being printed.
    """
    observer = _ErrorObserver()
    tags = observer.attach(algorithm)
    executive = algorithm.GetExecutive()
    executive_tags = observer.attach(executive) if executive is not None else []
    cancelled: list[BaseException] = []
    progress_tag = None
    if progress is not None:

        def on_progress(caller, event):
            if cancelled:
                return
            try:
                progress(caller.GetProgress())
            except OperationCancelled as exc:
                cancelled.append(exc)
                caller.SetAbortExecute(1)

        progress_tag = algorithm.AddObserver(vtkCommand.ProgressEvent, on_progress)
    try:
        algorithm.Update()
    finally:
        for tag in tags:
            algorithm.RemoveObserver(tag)
        for tag in executive_tags:
            executive.RemoveObserver(tag)
        if progress_tag is not None:
            algorithm.RemoveObserver(progress_tag)
    if cancelled:
        algorithm.SetAbortExecute(0)
        algorithm.Modified()
        raise cancelled[0]
    if observer.errors:
        # The algorithm's own message comes first; the executive's "returned failure" adds nothing for a reader.
        raise VTKError(f"{algorithm.GetClassName()}: {observer.errors[0]}")
    return algorithm.GetOutputDataObject(port)


def progress_for(algorithm: vtkAlgorithm) -> ProgressCallback:
    """A progress callback that forwards to ``algorithm.UpdateProgress`` and honours VTK's abort flag.

    Used by our ``VTKPythonAlgorithmBase`` subclasses to hand VTK's progress/abort machinery to a NumPy core.
    """

    def _progress(fraction: float) -> None:
        algorithm.UpdateProgress(fraction)
        if algorithm.GetAbortExecute() or (hasattr(algorithm, "CheckAbort") and algorithm.CheckAbort()):
            raise OperationCancelled(f"{algorithm.GetClassName()} was aborted")

    return _progress


def request_data(method):
    """Decorate a ``VTKPythonAlgorithmBase.RequestData`` so that it follows VTK's conventions whatever the NumPy core
    raises: a ``ValueError`` (bad input or parameters) becomes an ``ErrorEvent`` carrying its message and a failed
    request (0, so ``Update`` reports it and :func:`run_algorithm` raises :class:`VTKError`); a computation cancelled
    through :func:`progress_for` leaves the output empty and succeeds (1), as an aborted VTK filter does."""

    @functools.wraps(method)
    def guarded(self, request, in_info, out_info):
        try:
            return method(self, request, in_info, out_info)
        except OperationCancelled:
            return 1
        except ValueError as error:
            self.InvokeEvent(vtkCommand.ErrorEvent, str(error))
            return 0

    return guarded


def vtk_matrix(matrix: np.ndarray):
    """A ``vtkMatrix4x4`` holding the 4x4 ``matrix`` (row-major, as VTK stores it)."""
    from vtkmodules.vtkCommonMath import vtkMatrix4x4

    matrix = np.asarray(matrix, dtype=np.float64)
    if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
        raise ValueError(f"expected a finite 4x4 matrix, got shape {matrix.shape}")
    result = vtkMatrix4x4()
    result.DeepCopy(matrix.ravel().tolist())
    return result


def image_from_array(
    array: np.ndarray,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
    name: str = "scalars",
    *,
    cell_data: bool = False,
    share: bool = False,
) -> vtkImageData:
    """Wrap a ``(nz, ny, nx)`` array as a ``vtkImageData`` (identity direction).

    With ``cell_data=True`` the values go on the cells of an image with one more point per axis, the origin moved
    by half a voxel, so every voxel becomes a unit cell centred on its sample (used for voxel-face references).
    By default the returned image references a contiguous copy of the data kept alive by VTK. With ``share=True``
    a C-contiguous ``array`` in native byte order is not copied: VTK's array points at the NumPy memory and holds a
    reference to it (a non-contiguous one is copied once). The caller must then not write into ``array`` (VTK would
    not notice) - :meth:`app.volume.Volume.to_vtk` makes its array read-only for that reason.
    """
    array = np.asarray(array)
    if array.ndim != 3:
        raise ValueError(f"expected a 3D array (nz, ny, nx), got shape {array.shape}")
    nz, ny, nx = array.shape
    image = vtkImageData()
    image.SetSpacing(*map(float, spacing))
    if share and not array.dtype.isnative:
        array = array.astype(array.dtype.newbyteorder("="))  # VTK reads native byte order only
    flat = np.ascontiguousarray(array).reshape(-1)
    vtk_array = numpy_support.numpy_to_vtk(flat, deep=not share)
    vtk_array.SetName(name)
    if cell_data:
        image.SetDimensions(nx + 1, ny + 1, nz + 1)
        image.SetOrigin(*(float(o) - 0.5 * float(s) for o, s in zip(origin, spacing)))
        image.GetCellData().SetScalars(vtk_array)
    else:
        image.SetDimensions(nx, ny, nz)
        image.SetOrigin(*map(float, origin))
        image.GetPointData().SetScalars(vtk_array)
    return image


def array_from_image(image: vtkImageData, name: str | None = None) -> np.ndarray:
    """The point scalars of ``image`` as a ``(nz, ny, nx)`` array (a view on VTK's memory when possible)."""
    nx, ny, nz = image.GetDimensions()
    point_data = image.GetPointData()
    vtk_array = point_data.GetArray(name) if name else point_data.GetScalars()
    if vtk_array is None:
        raise ValueError("the image has no point scalars" + (f" named {name!r}" if name else ""))
    if vtk_array.GetNumberOfComponents() != 1:
        raise ValueError(f"expected one component, got {vtk_array.GetNumberOfComponents()}")
    return numpy_support.vtk_to_numpy(vtk_array).reshape(nz, ny, nx)


def direction_matrix(image: vtkImageData) -> np.ndarray:
    """The image's 3x3 direction matrix (columns: the world directions of i, j, k) as a float64 array."""
    matrix = image.GetDirectionMatrix()
    return np.array([[matrix.GetElement(r, c) for c in range(3)] for r in range(3)], dtype=np.float64)


def has_identity_direction(image: vtkImageData) -> bool:
    """Whether the image's axes are the world axes (what our filters that ignore the direction expect)."""
    return bool(np.allclose(direction_matrix(image), np.eye(3)))


def cell_arrays(cells) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``offsets`` (n_cells + 1) and flat ``connectivity`` of a ``vtkCellArray``, int64 (``[0]`` and ``[]``
    for None or an empty array)."""
    if cells is None or cells.GetNumberOfCells() == 0:
        return np.zeros(1, dtype=np.int64), np.empty(0, dtype=np.int64)
    offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64, copy=False)
    connectivity = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64, copy=False)
    return offsets, connectivity


def polydata_arrays(polydata: vtkPolyData) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(n, 3)`` and triangles ``(m, 3)`` of a polydata whose polys are all triangles.

    Strips are not converted here; triangulate first (vtkTriangleFilter) when the input may hold strips.
    """
    points = numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()) if polydata.GetPoints() else np.empty((0, 3))
    polys = polydata.GetPolys()
    if polys is None or polys.GetNumberOfCells() == 0:
        return np.asarray(points), np.empty((0, 3), dtype=np.int64)
    offsets, connectivity = cell_arrays(polys)
    if not np.all(np.diff(offsets) == 3):
        raise ValueError("polydata_arrays expects triangles only")
    return np.asarray(points), connectivity.reshape(-1, 3)


def vtk_points(points: np.ndarray):
    """A ``vtkPoints`` holding a deep copy of ``points`` ``(n, 3)``: float32 stays float32, anything else float64."""
    from vtkmodules.vtkCommonCore import vtkPoints

    array = np.asarray(points)
    array = np.ascontiguousarray(array, dtype=np.float32 if array.dtype == np.float32 else np.float64)
    result = vtkPoints()
    result.SetData(numpy_support.numpy_to_vtk(array.reshape(-1, 3), deep=True))
    return result


def cell_array_from_offsets(offsets: np.ndarray, connectivity: np.ndarray):
    """A ``vtkCellArray`` from CSR ``offsets`` (length n_cells + 1) and flat ``connectivity`` (deep copies)."""
    from vtkmodules.vtkCommonDataModel import vtkCellArray

    id_type = numpy_support.get_vtk_array_type(np.int64)
    cells = vtkCellArray()
    cells.SetData(
        numpy_support.numpy_to_vtk(np.ascontiguousarray(offsets, dtype=np.int64), deep=True, array_type=id_type),
        numpy_support.numpy_to_vtk(np.ascontiguousarray(connectivity, dtype=np.int64), deep=True, array_type=id_type),
    )
    return cells


def polydata_from_arrays(points: np.ndarray, triangles: np.ndarray) -> vtkPolyData:
    """A ``vtkPolyData`` with the given points ``(n, 3)`` and triangles ``(m, 3)`` (deep copies)."""
    triangles = np.asarray(triangles).reshape(-1, 3)
    polydata = vtkPolyData()
    polydata.SetPoints(vtk_points(points))
    polydata.SetPolys(cell_array_from_offsets(np.arange(0, 3 * len(triangles) + 1, 3), triangles.ravel()))
    return polydata
