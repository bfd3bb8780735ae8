"""Ring energy: how much concentric banding ("wood grain") a rendered frame of a round object shows.

A renderer that samples every ray at the same depths (a fixed step from the box entry, or the slices of
shear-warp and texture slicing) reconstructs a smooth surface crossed at a slant at quantised depths, which draws
rings around the point where the surface faces the camera. Jitter turns them into fine noise. To measure the
periodic component and not the noise, the frame's luminance is averaged over rings of equal radius around the
object's centre (the angular mean cancels uncorrelated noise but keeps rings, which are constant along their
circle); the radial profile's smooth trend (a Gaussian smoothing over ``trend_pixels``) is removed and the root
mean square of what remains is the ring energy.

Axis order: images are ``(height, width, 3)`` (or ``(height, width)``) with row 0 at the top; the centre is
``(col, row)`` in pixels (pixel centres at .5).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d


def radial_profile(image: np.ndarray, centre, radius: float) -> np.ndarray:
    """Mean luminance (Rec. 709 weights for RGB) over one-pixel-wide rings ``0 .. radius`` around ``centre``."""
    image = np.asarray(image, dtype=np.float64)
    if image.ndim == 3:
        image = image[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    if image.ndim != 2:
        raise ValueError(f"expected an (h, w) or (h, w, 3) image, got shape {image.shape}")
    if not radius >= 2:
        raise ValueError(f"radius must be at least 2 pixels, got {radius}")
    height, width = image.shape
    rows, cols = np.mgrid[0:height, 0:width]
    distance = np.hypot(cols + 0.5 - centre[0], rows + 0.5 - centre[1])
    bins = np.floor(distance).astype(np.int64)
    inside = bins < int(radius)
    sums = np.bincount(bins[inside], weights=image[inside], minlength=int(radius))
    counts = np.bincount(bins[inside], minlength=int(radius))
    return sums / np.maximum(counts, 1)


def ring_energy(image: np.ndarray, centre, radius: float, *, trend_pixels: float = 6.0,
                inner: float = 3.0) -> float:
    """RMS of the radial profile minus its smooth trend, over radii ``inner .. radius`` (luminance units).

    Parameters
    ----------
    image : ndarray, (h, w) or (h, w, 3)
        The frame, values in [0, 1].
    centre : (col, row)
        Centre of the rings in pixels.
    radius : float
        Outer radius (pixels) of the measured disc: keep it inside the object's silhouette.
    trend_pixels : float
        Standard deviation (pixels) of the Gaussian that gives the smooth trend; rings narrower than about
        twice this count as banding.
    inner : float
        Radii below this are left out (the centre ring averages too few pixels).
    """
    profile = radial_profile(image, centre, radius)
    trend = gaussian_filter1d(profile, trend_pixels, mode="nearest")
    residual = (profile - trend)[int(inner):]
    return float(np.sqrt(np.mean(residual**2)))


__all__ = ["radial_profile", "ring_energy"]
