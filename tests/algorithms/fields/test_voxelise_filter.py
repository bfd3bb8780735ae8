"""The VTK filter of voxelisation: a given grid or the grid of a second input, progress and abort, errors."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.common.progress import OperationCancelled
from algorithms.common.vtk_bridge import VTKError, array_from_image, direction_matrix, polydata_from_arrays, run_algorithm
from algorithms.fields.voxelise import VoxeliseFilter, voxelise
from algorithms.fields.voxelise import grid_of_image, image_on_grid

from ._voxelise_shapes import rotation, torus


@pytest.fixture(scope="module")
def ring():
    return torus(20.0, 6.0, around=96, across=48)


def test_filter_on_a_given_grid_matches_the_function(ring):
    grid = Grid.around((-27, 27, -27, 27, -7, 7), spacing=(0.8, 0.8, 1.6))
    voxelise_filter = VoxeliseFilter()
    voxelise_filter.SetInputDataObject(0, polydata_from_arrays(*ring))
    voxelise_filter.SetGrid(grid)
    image = run_algorithm(voxelise_filter)
    assert image.GetDimensions() == grid.dimensions
    assert np.allclose(image.GetSpacing(), grid.spacing) and np.allclose(image.GetOrigin(), grid.origin)
    assert np.array_equal(array_from_image(image), voxelise(*ring, grid))
    assert image.GetPointData().GetScalars().GetName() == "mask"
    assert voxelise_filter.GetReport().rule == "parity"


def test_filter_takes_the_grid_of_a_second_input_with_its_direction(ring):
    direction = rotation((0.0, 1.0, 1.0), 25.0)
    grid = Grid((70, 64, 40), (0.9, 0.9, 1.1), (-30.0, -28.0, -12.0), tuple(direction.ravel()))
    reference = image_on_grid(np.zeros(grid.shape, np.int16), grid, name="ct")
    assert grid_of_image(reference).same_as(grid)
    voxelise_filter = VoxeliseFilter()
    voxelise_filter.SetInputDataObject(0, polydata_from_arrays(*ring))
    voxelise_filter.SetInputDataObject(1, reference)
    voxelise_filter.SetInside("winding")
    image = run_algorithm(voxelise_filter)
    assert np.allclose(direction_matrix(image), direction)
    assert np.array_equal(array_from_image(image), voxelise(*ring, grid))
    assert voxelise_filter.GetReport().rule == "winding"


def test_filter_triangulates_polygons():
    from vtkmodules.vtkFiltersSources import vtkCubeSource
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData

    cube = vtkCubeSource()
    cube.SetBounds(1.5, 6.5, 2.5, 4.5, 0.5, 3.5)  # quads, with separate points per face: merge them first
    clean = vtkCleanPolyData()
    clean.SetInputConnection(cube.GetOutputPort())
    voxelise_filter = VoxeliseFilter()
    voxelise_filter.SetInputConnection(0, clean.GetOutputPort())
    voxelise_filter.SetGrid(Grid((9, 7, 5)))
    assert array_from_image(run_algorithm(voxelise_filter)).sum() == 5 * 2 * 3


def test_filter_errors_and_abort(ring):
    voxelise_filter = VoxeliseFilter()
    voxelise_filter.SetInputDataObject(0, polydata_from_arrays(*ring))
    with pytest.raises(VTKError, match="needs a grid"):
        run_algorithm(voxelise_filter)
    with pytest.raises(ValueError, match="inside rule"):
        voxelise_filter.SetInside("nonzero")
    with pytest.raises(ValueError, match="Grid"):
        voxelise_filter.SetGrid((10, 10, 10))
    voxelise_filter.SetGrid(Grid.around((-27, 27, -27, 27, -7, 7), voxels=128))

    def cancel(fraction):
        if fraction > 0.1:
            raise OperationCancelled("stop")

    with pytest.raises(OperationCancelled):
        run_algorithm(voxelise_filter, cancel)
    seen = []
    image = run_algorithm(voxelise_filter, seen.append)
    assert seen[-1] == 1.0 and array_from_image(image).sum() > 0
