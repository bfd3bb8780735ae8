"""Image comparison toolkit: known PSNR/RMSE of synthetic images, SSIM properties, masks, heat maps, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from algorithms.compare.image_metrics import (
    ImageComparison,
    compare_images,
    difference_heatmap,
    difference_image,
    foreground_mask,
    psnr,
    psnr_foreground,
    rmse,
    ssim,
)


@pytest.fixture
def gradient_image():
    """A smooth 48 x 64 colour image in [0, 1] with structure (ramps in x and y)."""
    y, x = np.mgrid[0:48, 0:64]
    return np.stack([x / 63.0, y / 47.0, 0.5 + 0.25 * np.sin(x / 5.0)], axis=-1)


def test_uniform_offset_gives_known_rmse_and_psnr(gradient_image):
    shifted = np.clip(gradient_image + 0.1, 0.0, 1.0)
    expected_mse = np.mean((shifted - gradient_image) ** 2)
    assert rmse(gradient_image, shifted) == pytest.approx(math.sqrt(expected_mse), rel=1e-12)
    assert psnr(gradient_image, shifted) == pytest.approx(10 * math.log10(1 / expected_mse), rel=1e-12)


def test_uint8_images_are_scaled_to_unit_range():
    a = np.zeros((16, 16, 3), np.uint8)
    b = np.full((16, 16, 3), 51, np.uint8)  # 0.2 everywhere
    assert rmse(a, b) == pytest.approx(0.2, abs=1e-12)
    assert psnr(a, b) == pytest.approx(-20 * math.log10(0.2), abs=1e-9)  # 13.98 dB
    # uint8 and float inputs compare directly
    assert psnr(a, b.astype(np.float64) / 255.0) == pytest.approx(psnr(a, b), abs=1e-12)


def test_identical_images_have_infinite_psnr_and_ssim_one(gradient_image):
    assert psnr(gradient_image, gradient_image) == math.inf
    assert rmse(gradient_image, gradient_image) == 0.0
    assert ssim(gradient_image, gradient_image) == pytest.approx(1.0, abs=1e-12)


def test_ssim_drops_with_noise_and_more_with_more_noise(gradient_image, rng):
    noise = rng.standard_normal(gradient_image.shape)
    slightly = np.clip(gradient_image + 0.02 * noise, 0, 1)
    strongly = np.clip(gradient_image + 0.2 * noise, 0, 1)
    s_slight, s_strong = ssim(gradient_image, slightly), ssim(gradient_image, strongly)
    assert 0.5 < s_slight < 1.0
    assert s_strong < s_slight - 0.2
    assert ssim(gradient_image, slightly) == pytest.approx(ssim(slightly, gradient_image), abs=1e-12)  # symmetric


def test_ssim_of_constant_images_is_the_luminance_term():
    # Constant images: no variance, so SSIM = (2 mu_x mu_y + C1) / (mu_x^2 + mu_y^2 + C1) exactly.
    a = np.full((20, 20, 3), 0.5)
    b = np.full((20, 20, 3), 0.3)
    c1 = 0.01**2
    expected = (2 * 0.5 * 0.3 + c1) / (0.5**2 + 0.3**2 + c1)
    assert ssim(a, b) == pytest.approx(expected, rel=1e-9)


def test_foreground_mask_and_foreground_psnr():
    a = np.zeros((20, 30, 3))
    b = np.zeros((20, 30, 3))
    a[5:10, 5:10] = 0.5  # 25 pixels in a
    b[5:10, 8:15] = 0.5  # 35 pixels in b, overlapping 10 of a's
    b[0, 0] = 0.5 / 255  # below the one-grey-level tolerance: still background
    mask = foreground_mask(a, b)
    assert mask.sum() == 25 + 35 - 10
    # 15 pixels only in a and 25 only in b differ by 0.5 in all channels, among 50 foreground pixels
    expected = 10 * math.log10(1 / (40 * 0.25 / 50))
    assert psnr_foreground(a, b) == pytest.approx(expected, rel=1e-12)
    assert psnr(a, b, mask=mask) == pytest.approx(expected, rel=1e-12)
    # a white background turns the dark pixels into foreground
    assert foreground_mask(a, b, background=(1, 1, 1)).all()


def test_blank_frames_have_undefined_foreground_psnr():
    blank = np.zeros((12, 12, 3), np.uint8)
    assert math.isnan(psnr_foreground(blank, blank))
    assert not psnr_foreground(blank, blank) >= 28.0  # a NaN never passes an acceptance check


def test_difference_image_and_heatmap():
    a = np.zeros((12, 14, 3))
    b = np.zeros((12, 14, 3))
    b[3, 4] = (0.1, 0.4, 0.2)
    diff = difference_image(a, b)
    assert diff.shape == (12, 14) and diff.dtype == np.float32
    assert diff[3, 4] == pytest.approx(0.4)
    assert np.count_nonzero(diff) == 1
    heat = difference_heatmap(a, b)
    assert heat.shape == (12, 14, 3) and heat.dtype == np.uint8
    assert heat[0, 0].sum() < 30  # inferno starts near black
    assert heat[3, 4].sum() > 500  # and ends pale yellow at vmax
    half = difference_heatmap(a, b, vmax=0.8)
    assert 30 < half[3, 4].sum() < heat[3, 4].sum()


def test_compare_images_collects_every_number():
    a = np.zeros((16, 16, 3), np.uint8)
    b = a.copy()
    b[4:8, 4:8] = 100
    result = compare_images(a, b)
    assert isinstance(result, ImageComparison)
    assert result.foreground_pixels == 16
    assert result.max_difference == pytest.approx(100 / 255)
    assert result.psnr_foreground == pytest.approx(-20 * math.log10(100 / 255), rel=1e-9)
    assert result.psnr == pytest.approx(psnr(a, b))
    assert result.rmse == pytest.approx(rmse(a, b))
    assert result.ssim == pytest.approx(ssim(a, b))
    assert set(result.as_dict()) == {"psnr_foreground", "psnr", "rmse", "ssim", "max_difference", "foreground_pixels"}


@pytest.mark.parametrize(
    "a, b, message",
    [
        (np.zeros((4, 4)), np.zeros((4, 4)), r"\(h, w, 3\)"),
        (np.zeros((4, 4, 4)), np.zeros((4, 4, 4)), r"\(h, w, 3\)"),
        (np.zeros((4, 4, 3)), np.zeros((4, 5, 3)), "differ in shape"),
        (np.zeros((4, 4, 3), np.uint16), np.zeros((4, 4, 3), np.uint16), "uint8"),
        (np.full((4, 4, 3), 1.5), np.zeros((4, 4, 3)), r"outside \[0, 1\]"),
        (np.full((4, 4, 3), np.nan), np.zeros((4, 4, 3)), "NaN"),
    ],
)
def test_invalid_images_are_rejected(a, b, message):
    with pytest.raises(ValueError, match=message):
        psnr(a, b)


def test_invalid_options_are_rejected():
    a = np.zeros((8, 8, 3))
    with pytest.raises(ValueError, match="selects no pixels"):
        psnr(a, a, mask=np.zeros((8, 8), bool))
    with pytest.raises(ValueError, match="boolean array"):
        rmse(a, a, mask=np.ones((8, 8)))
    with pytest.raises(ValueError, match="background"):
        foreground_mask(a, a, background=(0, 0, 2))
    with pytest.raises(ValueError, match="tolerance"):
        foreground_mask(a, a, tolerance=-0.1)
    with pytest.raises(ValueError, match="at least 11 x 11"):
        ssim(a, a)
    with pytest.raises(ValueError, match="vmax"):
        difference_heatmap(a, a, vmax=0)
