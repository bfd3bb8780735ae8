"""VTK's built-in surface extractors, run the way we run our own filters (:func:`run_algorithm`).

- :func:`contour`: isosurfaces by ``vtkFlyingEdges3D`` or ``vtkMarchingCubes`` (the references of marching cubes).
- :func:`vtk_threshold_surface`, :func:`vtk_voxel_surface`: the visible voxel faces by ``vtkThreshold`` and
  ``vtkDataSetSurfaceFilter`` (the reference of the voxel-face methods).
- :func:`vtk_stripper`: VTK's strip generator on the baseline's triangles (the reference of the tower strips).

Volumes are ``(nz, ny, nx)`` arrays or ``vtkImageData``; spacing and origin ``(x, y, z)`` in mm.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkDataSetAttributes, vtkImageData, vtkPolyData
from vtkmodules.vtkFiltersCore import (
    vtkFlyingEdges3D,
    vtkMarchingCubes,
    vtkStaticCleanPolyData,
    vtkStripper,
    vtkThreshold,
)
from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter

from ..common.mesh import TriangleMesh
from ..common.progress import ProgressCallback, scaled
from ..common.validation import validated_geometry, validated_solid
from ..common.vtk_bridge import VTKError, cell_arrays, image_from_array, run_algorithm

#: The isosurface extractors :func:`contour` runs, by name.
CONTOUR_METHODS = {"flying-edges": vtkFlyingEdges3D, "marching-cubes": vtkMarchingCubes}


def contour(
    image: vtkImageData,
    iso: float,
    *,
    method: str = "flying-edges",
    normals: bool = True,
    progress: ProgressCallback = None,
) -> vtkPolyData:
    """The isosurface ``value = iso`` of an image by VTK's ``vtkFlyingEdges3D`` or ``vtkMarchingCubes``.

    Parameters
    ----------
    image : vtkImageData
        The volume (its active point scalars are contoured); the surface is in the image's coordinates.
    iso : float
        The isovalue.
    method : {"flying-edges", "marching-cubes"}
        The extractor (:data:`CONTOUR_METHODS`).
    normals : bool
        Compute point normals (from the gradient). Scalars and gradients are not computed.
    progress : callable, optional
        Receives VTK's progress; may raise ``OperationCancelled``.

    Returns
    -------
    vtkPolyData
        A copy of the output (triangles), not connected to the pipeline.

    Raises
    ------
    ValueError
        For an unknown method.
    VTKError
        If VTK reports an error.
    """
    if method not in CONTOUR_METHODS:
        raise ValueError(f"method must be one of {', '.join(CONTOUR_METHODS)}, got {method!r}")
    algorithm = CONTOUR_METHODS[method]()
    algorithm.SetInputData(image)
    algorithm.SetValue(0, float(iso))
    algorithm.SetComputeNormals(int(normals))
    algorithm.SetComputeScalars(0)
    if hasattr(algorithm, "SetComputeGradients"):
        algorithm.SetComputeGradients(0)
    output = run_algorithm(algorithm, progress)
    polydata = output.NewInstance()
    polydata.ShallowCopy(output)
    return polydata


def vtk_stripper(faces: TriangleMesh, *, progress: ProgressCallback = None) -> vtkPolyData:
    """VTK's strip generator on the baseline triangles: ``vtkStaticCleanPolyData`` then ``vtkStripper``.

    ``faces`` are the baseline's voxel faces (:func:`algorithms.surfaces.voxel_faces.voxel_faces`, or any
    :class:`~algorithms.common.mesh.TriangleMesh`). The baseline gives every face its own four vertices, so no two faces
    share a point id and ``vtkStripper`` (which follows shared edges by id) could not join faces at all. Coincident
    points are therefore merged first (tolerance 0: exact duplicates only). ``vtkStripper`` keeps its default maximum of
    1000 triangles per strip. """
    clean = vtkStaticCleanPolyData()
    clean.SetInputData(faces.to_polydata())
    clean.SetTolerance(0.0)
    clean.ToleranceIsAbsoluteOn()
    stripper = vtkStripper()
    stripper.SetInputData(run_algorithm(clean, scaled(progress, 0.0, 0.3)))
    return run_algorithm(stripper, scaled(progress, 0.3, 1.0))


def vtk_threshold_surface(image, threshold: float, *, progress: ProgressCallback = None) -> vtkPolyData:
    """``vtkThreshold`` (cell scalars ``>= threshold``) then ``vtkDataSetSurfaceFilter`` on a cell-data image.

    ``image`` is made by ``image_from_array(volume, spacing, origin, cell_data=True)``: every voxel a cell.
    Returns the external faces of the kept cells as quads.
    """
    threshold_filter = vtkThreshold()
    threshold_filter.SetInputData(image)
    threshold_filter.SetInputArrayToProcess(
        0, 0, 0, vtkDataObject.FIELD_ASSOCIATION_CELLS, vtkDataSetAttributes.SCALARS
    )
    threshold_filter.SetThresholdFunction(vtkThreshold.THRESHOLD_BETWEEN)
    threshold_filter.SetLowerThreshold(float(threshold))
    threshold_filter.SetUpperThreshold(np.inf)
    surface = vtkDataSetSurfaceFilter()
    surface.SetInputData(run_algorithm(threshold_filter, scaled(progress, 0.0, 0.6)))
    return run_algorithm(surface, scaled(progress, 0.6, 1.0))


def vtk_voxel_surface(
    volume,
    threshold=None,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
    *,
    progress: ProgressCallback = None,
) -> tuple[np.ndarray, np.ndarray]:
    """VTK's built-in voxel surface: cell-data image, ``vtkThreshold`` (lower bound ``T``), ``vtkDataSetSurfaceFilter``.

    Parameters
    ----------
    volume : ndarray, shape (nz, ny, nx)
        Boolean mask or scalar volume, as for :func:`algorithms.surfaces.voxel_faces.voxel_faces` (a mask is passed
        to VTK as uint8 with ``T = 1``).
    threshold : float, optional
        ``T``: cells with value ``>= T`` are kept (required for a scalar volume).
    spacing, origin : (x, y, z)
        Voxel size and position of voxel ``(0, 0, 0)``'s centre, mm.

    Returns
    -------
    points : ndarray, shape (P, 3), float
        Surface points (shared between quads).
    quads : ndarray, shape (Q, 4), int64
        One quad per visible voxel face.

    Raises
    ------
    ValueError
        As :func:`algorithms.common.validation.validated_solid` and
        :func:`~algorithms.common.validation.validated_geometry`.
    VTKError
        If VTK fails, or returns a polygon that is not a quad.
    """
    array, threshold = validated_solid(volume, threshold)
    spacing_t, origin_t = validated_geometry(spacing, origin)
    if threshold is None:
        array, threshold = array.astype(np.uint8), 1.0
    image = image_from_array(array, spacing_t, origin_t, cell_data=True)
    polydata = vtk_threshold_surface(image, threshold, progress=progress)
    offsets, connectivity = cell_arrays(polydata.GetPolys())
    if np.any(np.diff(offsets) != 4):
        raise VTKError("vtkDataSetSurfaceFilter returned polygons that are not quads")
    points = polydata.GetPoints()
    points = numpy_support.vtk_to_numpy(points.GetData()) if points is not None else np.empty((0, 3))
    return np.asarray(points), connectivity.reshape(-1, 4)


__all__ = ["CONTOUR_METHODS", "contour", "vtk_stripper", "vtk_threshold_surface", "vtk_voxel_surface"]
