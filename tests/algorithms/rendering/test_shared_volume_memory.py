"""Issue 20 item 7 for the renderers: a volume and its ``vtkImageData`` share one block of memory (a 512^3 int16
volume is not held twice), nothing can write through the shared memory unnoticed, and VTK keeps the memory alive
on its own."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from algorithms.common.vtk_bridge import array_from_image, image_from_array
from app.volume import Volume


def _values(shape=(6, 5, 4), dtype=np.int16) -> np.ndarray:
    return np.arange(np.prod(shape), dtype=dtype).reshape(shape)


def test_image_from_array_copies_by_default_and_shares_when_asked():
    array = _values()
    copied = array_from_image(image_from_array(array))
    shared = array_from_image(image_from_array(array, share=True))
    assert not np.shares_memory(copied, array)
    assert np.shares_memory(shared, array)
    np.testing.assert_array_equal(shared, array)
    # A non-contiguous array cannot be shared: it is copied once, values in VTK's point order.
    strided = _values((6, 5, 8))[:, :, ::2]
    image = image_from_array(strided, share=True)
    assert not np.shares_memory(array_from_image(image), strided)
    np.testing.assert_array_equal(array_from_image(image), strided)


def test_vtk_keeps_the_shared_memory_alive_after_numpy_lets_go():
    image = image_from_array(_values(dtype=np.float32) * 0.5, share=True)  # the temporary is VTK's only owner
    gc.collect()
    np.testing.assert_array_equal(array_from_image(image), _values(dtype=np.float32) * 0.5)
    assert image.GetPointData().GetScalars().GetValue(7) == 3.5


def test_volume_to_vtk_shares_its_array_and_makes_it_read_only():
    mine = _values()
    volume = Volume(mine, spacing=(0.5, 0.75, 2.0), origin=(1.0, 2.0, 3.0))
    image = volume.to_vtk(local=True)
    scalars = array_from_image(image)
    assert np.shares_memory(scalars, volume.array) and np.shares_memory(scalars, mine)
    assert image.GetSpacing() == (0.5, 0.75, 2.0) and image.GetOrigin() == (0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="read-only"):
        volume.array[0, 0, 0] = 1
    assert mine.flags.writeable  # the caller's own array object is left as it was
    # A second image (another view, the world-frame one) shares the same memory too.
    world = volume.to_vtk()
    assert np.shares_memory(array_from_image(world), scalars) and world.GetOrigin() == (1.0, 2.0, 3.0)
    del volume, mine
    gc.collect()
    np.testing.assert_array_equal(array_from_image(image), _values())


@pytest.mark.parametrize("module, name", [("algorithms.rendering.raymarch.filter", "RaymarchFilter"),
                                          ("algorithms.rendering.shear_warp.filter", "ShearWarpFilter")])
def test_renderer_filters_sample_the_volumes_own_memory(module, name):
    import importlib

    from algorithms.common.camera import Camera
    from algorithms.common.transfer import TransferTable
    from algorithms.common.vtk_bridge import run_algorithm

    volume = Volume(np.zeros((8, 8, 8), dtype=np.int16))
    image = volume.to_vtk(local=True)
    flt = getattr(importlib.import_module(module), name)()
    flt.SetInputDataObject(image)
    flt.SetCamera(Camera(position=(3.5, 3.5, 40.0), focal_point=(3.5, 3.5, 3.5), view_up=(0.0, 1.0, 0.0)))
    flt.SetImageSize(8, 8)
    flt.SetTransferTable(TransferTable.from_points([(0, 1, 1, 1)], [(0, 0.5), (10, 1.0)], (0, 10)))
    run_algorithm(flt)
    sampled = flt._renderer.volume if hasattr(flt._renderer, "volume") else flt._renderer._values
    assert np.shares_memory(sampled, volume.array) and not sampled.flags.writeable
