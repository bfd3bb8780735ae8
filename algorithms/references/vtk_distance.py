"""VTK's built-ins for distance fields and mesh booleans, the references of :mod:`algorithms.fields.distance` and
:mod:`algorithms.fields.csg` (source 002, chapter 3).

- :func:`vtk_implicit_distance`: ``vtkImplicitPolyDataDistance`` evaluated at given points (exact distance to the
  nearest triangle through a cell locator, one thread; its sign from the normals at the nearest point, which is why
  our sign comes from voxelisation instead). Too slow for whole 256^3 grids: the tests and the benchmark sample
  voxels.
- :func:`vtk_loop_boolean`: ``vtkLoopBooleanPolyDataFilter`` (union, intersection, difference of two meshes).

Points are ``(x, y, z)`` LPS mm; distances in mm.
"""

from __future__ import annotations

import time

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ..common.vtk_bridge import polydata_from_arrays, run_algorithm

__all__ = ["BOOLEAN_OPERATIONS", "vtk_implicit_distance", "vtk_loop_boolean"]

BOOLEAN_OPERATIONS = {"union": 0, "intersection": 1, "difference": 2}


def _polydata(mesh) -> vtkPolyData:
    if isinstance(mesh, vtkPolyData):
        return mesh
    points, triangles = mesh
    return polydata_from_arrays(np.asarray(points, np.float64), np.asarray(triangles, np.int64))


def vtk_implicit_distance(mesh, samples) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances (mm, VTK's sign: negative inside by normals) and closest points of ``samples`` ``(q, 3)`` to
    ``mesh`` (a ``vtkPolyData`` or ``(points, triangles)``), by ``vtkImplicitPolyDataDistance``."""
    from vtkmodules.vtkFiltersCore import vtkImplicitPolyDataDistance

    implicit = vtkImplicitPolyDataDistance()
    implicit.SetInput(_polydata(mesh))
    samples = np.ascontiguousarray(samples, dtype=np.float64).reshape(-1, 3)
    values = np.empty(len(samples))
    closest = np.empty((len(samples), 3))
    point = [0.0, 0.0, 0.0]
    for q, sample in enumerate(samples):
        values[q] = implicit.EvaluateFunctionAndGetClosestPoint(sample.tolist(), point)
        closest[q] = point
    return values, closest


def vtk_loop_boolean(a, b, operation: str) -> tuple[vtkPolyData, float]:
    """``a (operation) b`` by ``vtkLoopBooleanPolyDataFilter`` (``operation`` in :data:`BOOLEAN_OPERATIONS`):
    the resulting mesh and the seconds it took. ``a`` and ``b`` are ``vtkPolyData`` or ``(points, triangles)``."""
    from vtkmodules.vtkFiltersGeneral import vtkLoopBooleanPolyDataFilter

    if operation not in BOOLEAN_OPERATIONS:
        raise ValueError(f"operation must be one of {', '.join(BOOLEAN_OPERATIONS)}, got {operation!r}")
    boolean = vtkLoopBooleanPolyDataFilter()
    boolean.SetInputData(0, _polydata(a))
    boolean.SetInputData(1, _polydata(b))
    boolean.SetOperation(BOOLEAN_OPERATIONS[operation])
    start = time.perf_counter()
    result = run_algorithm(boolean)
    return result, time.perf_counter() - start


def points_of(polydata: vtkPolyData) -> np.ndarray:
    """The points of a ``vtkPolyData`` as an ``(n, 3)`` array."""
    return numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()).astype(np.float64)
