"""Our VTK filters follow VTK's conventions whatever their NumPy core raises (``vtk_bridge.request_data``): bad
input is an error event with the core's message, an abort leaves an empty output, and neither prints a traceback
or leaves the filter unusable."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.common.progress import OperationCancelled
from algorithms.common.vtk_bridge import VTKError, image_from_array, polydata_from_arrays, run_algorithm
from algorithms.fields.distance.filter import DistanceFieldFilter
from algorithms.fields.voxelise.filter import VoxeliseFilter
from algorithms.meshing.isosurface_stuffing.filter import IsosurfaceStuffingFilter
from algorithms.surfaces.marching_cubes.filter import MarchingCubesFilter
from algorithms.surfaces.tower.filter import TowerFilter
from algorithms.surfaces.voxel_faces import VoxelFacesFilter


def _ball(n=24):
    k, j, i = np.indices((n, n, n))
    return (100.0 * (np.sqrt((i - n / 2) ** 2 + (j - n / 2) ** 2 + (k - n / 2) ** 2) < n / 3)).astype(np.float32)


def _octahedron():
    points = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64) * 8
    triangles = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return polydata_from_arrays(points, triangles)


def _image_filter(cls):
    algorithm = cls()
    algorithm.SetInputDataObject(0, image_from_array(_ball(), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)))
    if cls is MarchingCubesFilter:
        algorithm.SetValue(0, 50.0)
    elif cls is IsosurfaceStuffingFilter:
        algorithm.SetIsovalue(50.0)
        algorithm.SetLatticeSpacing(2.0)
    else:
        algorithm.SetThreshold(50.0)
    return algorithm


def _mesh_filter(cls):
    algorithm = cls()
    algorithm.SetInputDataObject(0, _octahedron())
    algorithm.SetGrid(Grid.around([-10, 10, -10, 10, -10, 10], voxels=16, padding=1))
    return algorithm


FILTERS = {
    "marching cubes": lambda: _image_filter(MarchingCubesFilter),
    "voxel faces": lambda: _image_filter(VoxelFacesFilter),
    "tower strips": lambda: _image_filter(TowerFilter),
    "isosurface stuffing": lambda: _image_filter(IsosurfaceStuffingFilter),
    "voxelise": lambda: _mesh_filter(VoxeliseFilter),
    "distance field": lambda: _mesh_filter(DistanceFieldFilter),
}


def _cancel_at_first_report(fraction):
    raise OperationCancelled("stopped by the test")


@pytest.mark.parametrize("name", FILTERS)
def test_an_aborted_filter_has_an_empty_output_and_runs_again(name):
    algorithm = FILTERS[name]()
    with pytest.raises(OperationCancelled):
        run_algorithm(algorithm, progress=_cancel_at_first_report)
    assert algorithm.GetOutputDataObject(0).GetNumberOfPoints() == 0
    assert run_algorithm(algorithm).GetNumberOfPoints() > 0  # nothing left over from the abort


def _nan_volume(algorithm):
    algorithm.SetInputDataObject(0, image_from_array(np.full((4, 4, 4), np.nan, np.float32), (1.0, 1.0, 1.0),
                                                     (0.0, 0.0, 0.0)))


SPOILED = {
    "marching cubes": (_nan_volume, "NaN"),
    "isosurface stuffing": (_nan_volume, "NaN"),
    "voxel faces": (lambda algorithm: algorithm.SetThreshold(float("nan")), "threshold must be finite"),
    "voxelise": (lambda algorithm: algorithm.SetGrid(None), "needs a grid"),
}


@pytest.mark.parametrize("name", SPOILED)
def test_bad_input_is_an_error_event_with_the_core_s_message(name):
    algorithm = FILTERS[name]()
    spoil, message = SPOILED[name]
    spoil(algorithm)
    with pytest.raises(VTKError, match=message):
        run_algorithm(algorithm)
