"""The application's view of the synthetic data: the CT phantom as a volume, and the bundled sample it makes."""

from __future__ import annotations

import numpy as np

from algorithms.datasets import volumes
from app.datasets import ct_head_phantom


def test_phantom_volume_wraps_the_array_with_its_geometry():
    volume = ct_head_phantom(shape=(12, 20, 16), spacing=(2.0, 1.5, 3.0), noise_hu=5.0, seed=3)
    np.testing.assert_array_equal(volume.array, volumes.ct_head_array((12, 20, 16), (2.0, 1.5, 3.0), noise_hu=5.0,
                                                                       seed=3))
    assert volume.array.dtype == np.int16
    assert volume.spacing == (2.0, 1.5, 3.0) and volume.units == "HU" and volume.modality == "CT"
    np.testing.assert_allclose(volume.centre, 0.0, atol=1e-12)  # centred on the origin, identity direction
    assert np.array_equal(volume.direction, np.eye(3))


def test_bundled_phantom_is_the_generator_bit_for_bit():
    """``python -m app.samples`` regenerates the sample from ct_head_phantom(); the file must not drift from it."""
    from app.io import load_volume
    from app.samples import sample_path

    bundled = load_volume(sample_path("ct"))
    generated = ct_head_phantom()
    assert bundled.array.dtype == generated.array.dtype
    assert np.array_equal(bundled.array, generated.array)
    assert bundled.spacing == generated.spacing
    np.testing.assert_allclose(bundled.origin, generated.origin)
