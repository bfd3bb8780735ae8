"""Comparing rendered images: PSNR, RMSE, SSIM, difference images and heat maps, and shading banding.

Every renderer of ours is checked against a VTK built-in by comparing the two frames of the same scene. The
functions here take two images of the same shape, each either ``(h, w, 3)`` uint8 (0-255) or floating point in
``[0, 1]``; both are converted to float64 in ``[0, 1]`` first, so a uint8 frame of VTK and a float frame of ours
compare directly.

Most of a volume rendering is background, which makes a whole-image PSNR look better the smaller the object is.
The *foreground* PSNR restricts the error to pixels where either image shows something (differs from the
background colour by more than a tolerance); that is the number the acceptance tests use.

References
----------
Z. Wang, A. C. Bovik, H. R. Sheikh, E. P. Simoncelli, "Image quality assessment: from error visibility to
structural similarity", IEEE Transactions on Image Processing 13(4), 600-612, 2004. DOI 10.1109/TIP.2003.819861
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

#: Rec. 709 / sRGB luminance weights, used to reduce colour images to the luminance SSIM works on.
LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)
#: SSIM constants of Wang et al. (2004): Gaussian window of standard deviation 1.5 pixels, 11 x 11 pixels wide.
SSIM_SIGMA = 1.5
SSIM_RADIUS = 5
SSIM_K1 = 0.01
SSIM_K2 = 0.03


def _as_float_image(image, name: str) -> np.ndarray:
    """``(h, w, 3)`` float64 in [0, 1] from a uint8 or float image (ValueError on anything else)."""
    array = np.asarray(image)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError(f"{name} must be an (h, w, 3) image, got shape {array.shape}")
    if array.dtype == np.uint8:
        return array.astype(np.float64) / 255.0
    if array.dtype.kind != "f":
        raise ValueError(f"{name} must be uint8 (0-255) or floating point in [0, 1], got dtype {array.dtype}")
    values = array.astype(np.float64)
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{name} contains NaN or infinite values")
    if values.size and (values.min() < 0.0 or values.max() > 1.0):
        raise ValueError(f"{name} has values outside [0, 1] ({values.min():.4g} to {values.max():.4g})")
    return values


def _pair(a, b) -> tuple[np.ndarray, np.ndarray]:
    first, second = _as_float_image(a, "a"), _as_float_image(b, "b")
    if first.shape != second.shape:
        raise ValueError(f"the images differ in shape: {first.shape} and {second.shape}")
    return first, second


def _background(background) -> np.ndarray:
    colour = np.asarray(background, dtype=np.float64).reshape(-1)
    if colour.shape != (3,) or np.any(colour < 0) or np.any(colour > 1):
        raise ValueError(f"background must be three values in [0, 1], got {background!r}")
    return colour


def _mean_squared_error(first: np.ndarray, second: np.ndarray, mask) -> float:
    squared = (first - second) ** 2
    if mask is None:
        return float(squared.mean())
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != first.shape[:2]:
        raise ValueError(f"mask must be a boolean array of shape {first.shape[:2]}, got {mask.dtype} {mask.shape}")
    if not mask.any():
        raise ValueError("mask selects no pixels")
    return float(squared[mask].mean())


def foreground_mask(a, b, *, background=(0.0, 0.0, 0.0), tolerance: float = 1.0 / 255.0) -> np.ndarray:
    """Pixels where either image differs from ``background`` by more than ``tolerance`` in some channel.

    Parameters
    ----------
    a, b : ndarray, shape (h, w, 3)
        uint8 or float in [0, 1].
    background : 3 floats in [0, 1]
        The colour of empty pixels.
    tolerance : float
        Largest per-channel difference (in [0, 1] units) still counted as background; the default is one grey level
        of an 8-bit image.

    Returns
    -------
    ndarray, shape (h, w), bool
    """
    first, second = _pair(a, b)
    if not tolerance >= 0:
        raise ValueError(f"tolerance must be non-negative, got {tolerance}")
    colour = _background(background)
    differs_a = np.abs(first - colour).max(axis=2) > tolerance
    differs_b = np.abs(second - colour).max(axis=2) > tolerance
    return differs_a | differs_b


def rmse(a, b, *, mask=None) -> float:
    """Root-mean-square difference over all channels (of the ``mask`` pixels), in [0, 1] units."""
    first, second = _pair(a, b)
    return math.sqrt(_mean_squared_error(first, second, mask))


def psnr(a, b, *, mask=None) -> float:
    """Peak signal-to-noise ratio in dB with peak 1.0: ``10 log10(1 / MSE)``; ``inf`` for identical images.

    ``mask`` (bool, ``(h, w)``) restricts the mean squared error to the selected pixels (ValueError if it selects
    none).
    """
    first, second = _pair(a, b)
    mse = _mean_squared_error(first, second, mask)
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def psnr_foreground(a, b, *, background=(0.0, 0.0, 0.0)) -> float:
    """PSNR (dB) over :func:`foreground_mask` (default tolerance).

    Returns NaN when neither image shows anything: the foreground PSNR is undefined then, and a NaN makes any
    ``psnr >= bound`` check fail instead of letting two blank frames pass.
    """
    mask = foreground_mask(a, b, background=background)
    if not mask.any():
        return math.nan
    return psnr(a, b, mask=mask)


def _luminance(image: np.ndarray) -> np.ndarray:
    return image @ np.asarray(LUMINANCE_WEIGHTS)


def ssim(a, b) -> float:
    """Mean structural similarity of the luminance of two images (Wang et al. 2004).

    Gaussian-weighted local statistics (standard deviation 1.5 pixels, window 11 x 11), ``K1 = 0.01``,
    ``K2 = 0.03``, dynamic range 1, averaged over the pixels whose whole window lies inside the image (the
    "valid" region, as in the authors' reference implementation). 1 for identical images, lower the more their
    local structure differs. Images must be at least 11 x 11 pixels.
    """
    from scipy.ndimage import gaussian_filter

    first, second = _pair(a, b)
    height, width = first.shape[:2]
    size = 2 * SSIM_RADIUS + 1
    if height < size or width < size:
        raise ValueError(f"SSIM needs images of at least {size} x {size} pixels, got {width} x {height}")
    x, y = _luminance(first), _luminance(second)
    truncate = SSIM_RADIUS / SSIM_SIGMA

    def local_mean(image: np.ndarray) -> np.ndarray:
        return gaussian_filter(image, SSIM_SIGMA, truncate=truncate, mode="reflect")

    mu_x, mu_y = local_mean(x), local_mean(y)
    var_x = local_mean(x * x) - mu_x * mu_x
    var_y = local_mean(y * y) - mu_y * mu_y
    cov_xy = local_mean(x * y) - mu_x * mu_y
    c1, c2 = SSIM_K1**2, SSIM_K2**2
    index = ((2 * mu_x * mu_y + c1) * (2 * cov_xy + c2)) / ((mu_x**2 + mu_y**2 + c1) * (var_x + var_y + c2))
    valid = index[SSIM_RADIUS : height - SSIM_RADIUS, SSIM_RADIUS : width - SSIM_RADIUS]
    return float(valid.mean())


def difference_image(a, b) -> np.ndarray:
    """Largest absolute per-channel difference of every pixel, ``(h, w)`` float32 in [0, 1]."""
    first, second = _pair(a, b)
    return np.abs(first - second).max(axis=2).astype(np.float32)


def difference_heatmap(a, b, *, vmax: float | None = None) -> np.ndarray:
    """:func:`difference_image` shown with the perceptually uniform "inferno" colour map, ``(h, w, 3)`` uint8.

    Black is no difference; ``vmax`` (in [0, 1] units, default: the largest difference present, at least one 8-bit
    grey level) maps to pale yellow, larger differences saturate.
    """
    from matplotlib import colormaps

    difference = difference_image(a, b)
    if vmax is None:
        vmax = max(float(difference.max()), 1.0 / 255.0)
    elif not vmax > 0:
        raise ValueError(f"vmax must be positive, got {vmax}")
    colours = colormaps["inferno"](np.clip(difference / vmax, 0.0, 1.0))[..., :3]
    return np.clip(np.rint(colours * 255.0), 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class ImageComparison:
    """All the numbers of :func:`compare_images` (PSNR in dB, differences in [0, 1] units)."""

    psnr_foreground: float
    psnr: float
    rmse: float
    ssim: float
    max_difference: float
    foreground_pixels: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def compare_images(a, b, *, background=(0.0, 0.0, 0.0)) -> ImageComparison:
    """Foreground PSNR, whole-image PSNR, RMSE, SSIM, largest difference and foreground size of two images."""
    mask = foreground_mask(a, b, background=background)
    return ImageComparison(
        psnr_foreground=psnr(a, b, mask=mask) if mask.any() else math.nan,
        psnr=psnr(a, b),
        rmse=rmse(a, b),
        ssim=ssim(a, b),
        max_difference=float(difference_image(a, b).max()),
        foreground_pixels=int(mask.sum()),
    )


def shading_banding(image, mask) -> float:
    """How much a shaded image bands: mean absolute discrete Laplacian of its luminance over ``mask``.

    Smooth shading of a smooth surface has a small second derivative everywhere; quantised normals (shear-warp's
    normal table, source 004 section 5.2.7) turn it into flat bands separated by steps, which the Laplacian picks
    up. ``image`` is ``(h, w, 3)`` uint8 or float in [0, 1]; ``mask`` a boolean ``(h, w)`` selecting pixels well
    inside the object (their 4 neighbours are used).
    """
    luminance = _luminance(_as_float_image(image, "image"))
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != luminance.shape or not mask[1:-1, 1:-1].any():
        raise ValueError("mask must be a boolean (h, w) array selecting interior pixels")
    laplacian = (
        luminance[:-2, 1:-1] + luminance[2:, 1:-1] + luminance[1:-1, :-2] + luminance[1:-1, 2:]
        - 4.0 * luminance[1:-1, 1:-1]
    )
    return float(np.abs(laplacian[mask[1:-1, 1:-1]]).mean())
