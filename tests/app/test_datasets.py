"""The application's view of the synthetic data: the CT phantom (FORBILD head) as a volume, the bundled sample it
makes, the same sample as a DICOM series, and the earlier egg-shaped phantom."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.datasets import forbild, volumes
from app.datasets import ct_head_phantom, egg_head_phantom


def test_phantom_volume_wraps_the_array_with_its_geometry():
    volume = ct_head_phantom(shape=(12, 20, 16), spacing=(12.0, 14.0, 21.0), noise_hu=5.0, seed=3)
    np.testing.assert_array_equal(volume.array, forbild.forbild_head_array((12, 20, 16), (12.0, 14.0, 21.0),
                                                                           noise_hu=5.0, seed=3))
    assert volume.array.dtype == np.int16
    assert volume.spacing == (12.0, 14.0, 21.0) and volume.units == "HU" and volume.modality == "CT"
    np.testing.assert_allclose(volume.centre, forbild.GRID_CENTRE, atol=1e-9)  # the head and the table in view
    assert np.array_equal(volume.direction, np.eye(3))
    # the head is centred on the LPS origin: the brain's 50 HU up and left of it, air in front of the face
    clean = ct_head_phantom(shape=(12, 20, 16), spacing=(12.0, 14.0, 21.0))
    index = np.round(clean.world_to_index((30.0, -20.0, 40.0))).astype(int)
    assert clean.array[index[2], index[1], index[0]] == 50
    assert clean.array[0, 0, 0] == -1000  # the corner in front of the face, below it and on the right


def test_without_spacing_a_grid_covers_the_sample_field_of_view():
    volume = ct_head_phantom(shape=(22, 40, 32))
    lo, hi = np.asarray(volume.world_bounds).reshape(3, 2).T
    sample_fov = np.array(forbild.SAMPLE_SHAPE[::-1]) * np.array(forbild.SAMPLE_SPACING)
    np.testing.assert_allclose(hi - lo + np.array(volume.spacing), sample_fov)


def test_egg_phantom_is_the_earlier_generator():
    volume = egg_head_phantom(shape=(12, 20, 16), spacing=(2.0, 1.5, 3.0), noise_hu=5.0, seed=3)
    np.testing.assert_array_equal(volume.array, volumes.ct_head_array((12, 20, 16), (2.0, 1.5, 3.0), noise_hu=5.0,
                                                                       seed=3))
    np.testing.assert_allclose(volume.centre, 0.0, atol=1e-12)


@pytest.mark.slow
def test_bundled_sample_is_the_generator_bit_for_bit():
    """``python -m app.samples`` regenerates the sample from ct_head_phantom(); the file must not drift from it."""
    from app.samples import load_sample

    bundled = load_sample("ct")
    generated = ct_head_phantom()
    assert bundled.array.dtype == generated.array.dtype
    assert np.array_equal(bundled.array, generated.array)
    assert bundled.spacing == generated.spacing
    np.testing.assert_allclose(bundled.origin, generated.origin)


def test_dicom_sample_reads_back_as_the_bundled_volume(tmp_path, monkeypatch):
    """``sample:dicom`` is written once into the user's cache (deterministic UIDs) and reads as the NIfTI does."""
    from app.io import load_volume
    from app.samples import dicom_sample_folder, load_sample, resolve_path

    monkeypatch.setenv("VOXELSCOPE_CACHE_DIR", str(tmp_path / "cache"))
    folder = resolve_path("sample:dicom")
    assert folder == dicom_sample_folder() and folder.parent.parent == tmp_path / "cache"
    files = sorted(folder.iterdir())
    assert len(files) == forbild.SAMPLE_SHAPE[0]
    series = load_volume(folder)
    bundled = load_sample("ct")
    assert np.array_equal(series.array, bundled.array)
    np.testing.assert_allclose(series.spacing, bundled.spacing, atol=1e-6)
    np.testing.assert_allclose(series.origin, bundled.origin, atol=1e-4)
    assert series.modality == "CT" and series.units == "HU"
    # asked again, the same folder is found, not written again
    stamps = {path.name: path.stat().st_mtime_ns for path in files}
    assert dicom_sample_folder() == folder
    assert {path.name: path.stat().st_mtime_ns for path in folder.iterdir()} == stamps
