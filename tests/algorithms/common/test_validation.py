"""The shared input validators: what each accepts and returns, and every ValueError with its message."""

from __future__ import annotations

import math

import numpy as np
import pytest

from algorithms.common.validation import (
    validated_count,
    validated_distance,
    validated_float_volume,
    validated_geometry,
    validated_image_size,
    validated_levels,
    validated_numeric_volume,
    validated_origin,
    validated_shape,
    validated_solid,
    validated_spacing,
    validated_volume,
)


# -- volumes ----------------------------------------------------------------------------------------------------
def test_shape_is_three_ints_and_says_why_not():
    assert validated_shape(np.array([2, 3, 4])) == (2, 3, 4)
    assert validated_shape((1, 1, 1)) == (1, 1, 1)
    with pytest.raises(ValueError, match=r"expected a 3D volume \(a real \(nz, ny, nx\) 3D array\), got .* \(4, 4\)"):
        validated_shape((4, 4))
    with pytest.raises(ValueError, match=r"the volume is empty \(shape \(0, 3, 3\)\)"):
        validated_shape((0, 3, 3))
    with pytest.raises(ValueError, match=r"at least 2 voxels along every axis \(at least 2 samples .*\(3, 1, 3\)"):
        validated_shape((3, 1, 3), min_size=2)
    with pytest.raises(ValueError, match=r"got shape \(1, 2, 2\) after stride 2$"):
        validated_shape((1, 2, 2), min_size=2, note=" after stride 2")


def test_volume_keeps_the_array_and_rejects_what_is_not_a_real_volume():
    array = np.zeros((2, 3, 4), dtype=np.int16)
    assert validated_volume(array) is array
    mask = np.ones((1, 1, 1), dtype=bool)
    assert validated_volume(mask) is mask
    with pytest.raises(ValueError, match="expected a 3D volume"):
        validated_volume(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="the volume is empty"):
        validated_volume(np.zeros((2, 0, 2)))
    with pytest.raises(ValueError, match="at least 2 voxels"):
        validated_volume(np.zeros((2, 1, 2)), min_size=2)
    for dtype in (complex, object, "U1"):
        with pytest.raises(ValueError, match=r"expected real scalar values: a boolean mask or a real-valued volume"):
            validated_volume(np.zeros((2, 2, 2), dtype=dtype))
    infinite = np.zeros((2, 2, 2))
    infinite[1, 1, 1] = np.inf
    assert validated_volume(infinite) is infinite  # allowed unless asked
    with pytest.raises(ValueError, match="the volume contains NaN or infinite values"):
        validated_volume(infinite, finite=True)
    with pytest.raises(ValueError, match="NaN"):
        validated_volume(np.full((2, 2, 2), np.nan), finite=True)


def test_numeric_volume_is_what_the_kernels_take():
    mask = np.zeros((2, 3, 4), dtype=bool)
    mask[1, 2, 3] = True
    as_bytes = validated_numeric_volume(mask)
    assert as_bytes.dtype == np.uint8 and as_bytes[1, 2, 3] == 1 and as_bytes.sum() == 1
    half = validated_numeric_volume(np.ones((2, 2, 2), dtype=np.float16))
    assert half.dtype == np.float32
    swapped = np.arange(8, dtype=">i4").reshape(2, 2, 2)
    native = validated_numeric_volume(swapped)
    assert native.dtype.isnative and np.array_equal(native, swapped)
    strided = np.zeros((4, 4, 4), dtype=np.int16)[::2]
    assert validated_numeric_volume(strided).flags.c_contiguous
    contiguous = np.zeros((2, 2, 2), dtype=np.float32)
    assert np.shares_memory(validated_numeric_volume(contiguous), contiguous)  # no copy when none is needed
    with pytest.raises(ValueError, match="at least 2 voxels"):
        validated_numeric_volume(np.zeros((4, 4, 1)), min_size=2)
    with pytest.raises(ValueError, match="NaN"):
        validated_numeric_volume(np.full((2, 2, 2), np.nan), finite=True)


def test_float_volume_is_a_private_read_only_copy():
    source = np.arange(8, dtype=np.uint8).reshape(2, 2, 2)
    volume = validated_float_volume(source)
    assert volume.dtype == np.float32 and not volume.flags.writeable and volume.flags.c_contiguous
    source[0, 0, 0] = 99
    assert volume[0, 0, 0] == 0
    assert validated_float_volume(np.ones((2, 2, 2), dtype=bool)).dtype == np.float32
    with pytest.raises(ValueError, match="3D volume"):
        validated_float_volume(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="at least 2 voxels"):
        validated_float_volume(np.zeros((1, 4, 4)))
    with pytest.raises(ValueError, match="real-valued"):
        validated_float_volume(np.zeros((2, 2, 2), dtype=complex))
    with pytest.raises(ValueError, match="NaN or infinite"):
        validated_float_volume(np.full((2, 2, 2), -np.inf))


@pytest.mark.parametrize(
    ("volume", "threshold", "message"),
    [
        (np.ones((3, 3)), 1, "expected a 3D volume"),
        (np.ones((0, 3, 3), dtype=bool), None, "the volume is empty"),
        (np.ones((2, 2, 2), dtype=complex), 1, "boolean mask or a real-valued volume"),
        (np.ones((2, 2, 2)), None, "a scalar volume needs a threshold"),
        (np.ones((2, 2, 2), dtype=bool), 1, "already solid/empty"),
        (np.ones((2, 2, 2)), np.nan, "threshold must be finite"),
        (np.ones((2, 2, 2)), "high", "threshold must be a number"),
    ],
)
def test_solid_errors(volume, threshold, message):
    with pytest.raises(ValueError, match=message):
        validated_solid(volume, threshold)


def test_solid_returns_the_array_and_a_float_threshold():
    mask = np.ones((1, 1, 1), dtype=bool)
    assert validated_solid(mask) == (mask, None)
    values = np.zeros((2, 2, 2), dtype=np.int16)
    array, threshold = validated_solid(values, np.int16(300))
    assert array is values and threshold == 300.0 and type(threshold) is float


# -- geometry and isovalues ---------------------------------------------------------------------------------------
def test_spacing_origin_and_geometry():
    spacing = validated_spacing(np.array([0.5, 1, 2]))
    assert spacing.dtype == np.float64 and spacing.tolist() == [0.5, 1.0, 2.0]
    assert validated_origin((-1, 0, 2.5)).tolist() == [-1.0, 0.0, 2.5]
    assert validated_geometry([1, 2, 3], np.zeros(3)) == ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0))
    for bad in ((1.0, 1.0), (1.0, 0.0, 1.0), (1.0, -1.0, 1.0), (1.0, np.inf, 1.0), (1.0, np.nan, 1.0), None, "abc"):
        with pytest.raises(ValueError, match=r"spacing must be three positive millimetre values \(x, y, z\)"):
            validated_spacing(bad)
    for bad in ((0.0, 0.0), (0.0, np.nan, 0.0), (np.inf, 0.0, 0.0), None):
        with pytest.raises(ValueError, match=r"origin must be three finite millimetre values \(x, y, z\)"):
            validated_origin(bad)
    with pytest.raises(ValueError, match="spacing and origin must be three numbers each"):
        validated_geometry((1.0, 1.0, 1.0), None)
    with pytest.raises(ValueError, match="spacing and origin must be three numbers each"):
        validated_geometry(("a", 1.0, 1.0), (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="spacing must be three positive"):
        validated_geometry((1.0, 1.0), (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="origin must be three finite"):
        validated_geometry((1.0, 1.0, 1.0), (0.0, np.inf, 0.0))


def test_levels():
    assert validated_levels(0.5).tolist() == [0.5]
    assert validated_levels([1, 3, 2]).tolist() == [1.0, 3.0, 2.0]
    with pytest.raises(ValueError, match="give one isovalue or a sequence of isovalues"):
        validated_levels([])
    with pytest.raises(ValueError, match="give one isovalue or a sequence of isovalues"):
        validated_levels([[0.5]])
    with pytest.raises(ValueError, match="isovalues must be finite numbers"):
        validated_levels([0.0, np.inf])
    with pytest.raises(ValueError, match="isovalues must be distinct"):
        validated_levels([0.5, 0.5])


# -- options ------------------------------------------------------------------------------------------------------
def test_count():
    assert validated_count(3, "slices") == 3
    assert validated_count(np.int64(2), "stride") == 2
    assert validated_count(4.0, "samples") == 4 and type(validated_count(4.0, "samples")) is int
    for bad in (0, -1, 1.5, True, np.bool_(True), "2", None):
        with pytest.raises(ValueError, match=r"stride must be a positive integer \(a note\), got"):
            validated_count(bad, "stride", note=" (a note)")


def test_distance():
    assert validated_distance(2, "slice_distance") == 2.0
    for bad in (0.0, -1.0, math.inf, math.nan, None, "far"):
        with pytest.raises(ValueError, match="sample_distance must be a positive number of mm"):
            validated_distance(bad, "sample_distance")


def test_image_size():
    assert validated_image_size(640, np.int64(480)) == (640, 480)
    assert validated_image_size(8.0, 4) == (8, 4)
    for width, height in ((8.5, 8), (8, 2.5), (True, 8), (8, False)):
        with pytest.raises(ValueError, match="image size must be whole pixels"):
            validated_image_size(width, height)
    for width, height in ((0, 8), (8, -1)):
        with pytest.raises(ValueError, match="image size must be positive"):
            validated_image_size(width, height)
