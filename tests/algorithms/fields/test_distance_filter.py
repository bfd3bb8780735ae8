"""``DistanceFieldFilter`` and ``CsgFilter``: the cores through VTK's pipeline (grid, progress, errors)."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.common.vtk_bridge import VTKError, array_from_image, polydata_from_arrays, run_algorithm
from algorithms.fields.csg import combine
from algorithms.fields.distance import signed_distance
from algorithms.fields.distance import CsgFilter, DistanceFieldFilter

from ._voxelise_shapes import sphere


def _field_filter(mesh, grid):
    algorithm = DistanceFieldFilter()
    algorithm.SetInputDataObject(0, polydata_from_arrays(*mesh))
    algorithm.SetGrid(grid)
    algorithm.SetBand(3.0)
    return algorithm


def test_filters_match_the_cores():
    grid = Grid.around((-20, 30, -20, 20, -20, 20), spacing=1.0, padding=2)
    a = sphere(15.0, around=64, across=32)
    b = sphere(12.0, around=64, across=32, centre=(15.0, 0.0, 0.0))
    fractions = []
    images = []
    for mesh in (a, b):
        algorithm = _field_filter(mesh, grid)
        image = run_algorithm(algorithm, progress=fractions.append)
        expected = signed_distance(*mesh, grid, band_mm=3.0).values
        assert np.array_equal(array_from_image(image), expected)
        images.append(image)
    assert fractions and fractions[-1] == pytest.approx(1.0)
    csg = CsgFilter()
    csg.SetOperation("difference")
    csg.SetBlend(1.0)
    for image in images:
        csg.AddInputDataObject(0, image)
    result = array_from_image(run_algorithm(csg))
    fields = [array_from_image(image) for image in images]
    assert np.array_equal(result, combine(fields, "difference", blend_mm=1.0))


def test_filters_report_errors():
    algorithm = DistanceFieldFilter()
    algorithm.SetInputDataObject(0, polydata_from_arrays(*sphere(5.0, around=16, across=8)))
    with pytest.raises(VTKError, match="needs a grid"):
        run_algorithm(algorithm)
    with pytest.raises(ValueError, match="outside"):
        algorithm.SetOutside("fill")
    one = _field_filter(sphere(5.0, around=16, across=8), Grid((16, 16, 16), (1, 1, 1), (-8, -8, -8)))
    two = _field_filter(sphere(5.0, around=16, across=8), Grid((12, 16, 16), (1, 1, 1), (-6, -8, -8)))
    csg = CsgFilter()
    csg.AddInputDataObject(0, run_algorithm(one))
    csg.AddInputDataObject(0, run_algorithm(two))
    with pytest.raises(VTKError, match="another grid"):
        run_algorithm(csg)
