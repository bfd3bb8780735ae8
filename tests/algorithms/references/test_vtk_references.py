"""The VTK built-ins we compare against, run through one helper each: contouring and the volume mappers' set-up."""

from __future__ import annotations

import numpy as np
import pytest
from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D, vtkMarchingCubes
from vtkmodules.vtkRenderingCore import vtkVolumeProperty

from algorithms import compare as sc
from algorithms.common.progress import OperationCancelled
from algorithms.common.vtk_bridge import image_from_array, polydata_arrays, run_algorithm
from algorithms.datasets.volumes import sphere_field
from algorithms.references.vtk_surfaces import contour
from algorithms.references.vtk_volume_mappers import volume_prop


@pytest.mark.parametrize(("method", "algorithm_class"), [("flying-edges", vtkFlyingEdges3D),
                                                         ("marching-cubes", vtkMarchingCubes)])
def test_contour_is_the_vtk_filter(method, algorithm_class):
    image = image_from_array(sphere_field((20, 22, 24), 7.0), (0.5, 1.0, 1.5), (3.0, -2.0, 1.0))
    ours = contour(image, 0.0, method=method)
    direct = algorithm_class()
    direct.SetInputData(image)
    direct.SetValue(0, 0.0)
    direct.SetComputeScalars(0)
    reference = run_algorithm(direct)
    comparison = sc.same_triangles(*polydata_arrays(ours), *polydata_arrays(reference))
    assert comparison.equal and comparison.count_a > 100, comparison.summary()
    assert ours.GetPointData().GetNormals() is not None and ours.GetPointData().GetScalars() is None
    assert contour(image, 0.0, method=method, normals=False).GetPointData().GetNormals() is None
    # A copy, not the pipeline's output: running again does not change the first result.
    count = ours.GetNumberOfCells()
    contour(image, 3.0, method=method)
    assert ours.GetNumberOfCells() == count


def test_contour_progress_and_errors():
    image = image_from_array(sphere_field((30, 30, 30), 10.0))
    seen = []
    contour(image, 0.0, progress=seen.append)
    assert seen and seen[-1] == 1.0

    def cancel(fraction):
        raise OperationCancelled("stop")

    with pytest.raises(OperationCancelled):
        contour(image, 0.0, method="marching-cubes", progress=cancel)
    with pytest.raises(ValueError, match="method must be one of flying-edges, marching-cubes"):
        contour(image, 0.0, method="surface-nets")


def test_volume_prop_fixes_the_sample_distance():
    image = image_from_array(np.zeros((4, 5, 6), dtype=np.int16), (0.5, 0.5, 2.0))
    properties = vtkVolumeProperty()
    gpu = volume_prop(image, properties, mapper="gpu", sample_distance=0.25)
    mapper = gpu.GetMapper()
    assert mapper.GetClassName().endswith("GPUVolumeRayCastMapper")
    assert (mapper.GetAutoAdjustSampleDistances(), mapper.GetLockSampleDistanceToInputSpacing(),
            mapper.GetUseJittering()) == (0, 0, 0)
    assert mapper.GetSampleDistance() == 0.25 and mapper.GetInput() is image
    assert mapper.GetBlendMode() == mapper.COMPOSITE_BLEND
    assert gpu.GetProperty() is properties and gpu.GetUserMatrix() is None
    placement = np.eye(4)
    placement[:3, 3] = (10.0, 20.0, 30.0)
    cpu = volume_prop(image, properties, mapper="cpu", sample_distance=0.5, user_matrix=placement)
    mapper = cpu.GetMapper()
    assert mapper.GetClassName() == "vtkFixedPointVolumeRayCastMapper"
    assert (mapper.GetAutoAdjustSampleDistances(), mapper.GetSampleDistance(), mapper.GetInteractiveSampleDistance(),
            mapper.GetImageSampleDistance()) == (0, 0.5, 0.5, 1.0)
    assert [cpu.GetUserMatrix().GetElement(r, 3) for r in range(3)] == [10.0, 20.0, 30.0]
    with pytest.raises(ValueError, match="mapper must be one of gpu, cpu"):
        volume_prop(image, properties, mapper="ospray", sample_distance=0.5)
    with pytest.raises(ValueError, match="sample_distance must be a positive number of mm"):
        volume_prop(image, properties, sample_distance=0.0)
