"""Input validation shared by every algorithm: volumes, geometry, isovalues, counts, distances and image sizes.

Each core validates its inputs up front with these functions, so the same mistake gets the same ``ValueError``
everywhere, saying exactly what is wrong. Volumes are NumPy arrays ``(nz, ny, nx)`` indexed ``[k, j, i]``;
spacing and origin are given in ``(x, y, z)`` order, in mm.

What each function accepts and returns:

- :func:`validated_shape`: a volume shape, at least ``min_size`` voxels per axis.
- :func:`validated_volume`: a 3D boolean or real array, unchanged (optionally free of NaN and infinity).
- :func:`validated_numeric_volume`: the same in a form numba kernels compile once for (booleans read as uint8,
  float16 as float32, native byte order, C order).
- :func:`validated_float_volume`: a private, read-only float32 copy (the software renderers sample it).
- :func:`validated_solid`: a boolean mask, or a scalar volume with the threshold that makes it one.
- :func:`validated_spacing`, :func:`validated_origin`, :func:`validated_geometry`: voxel size and position.
- :func:`validated_levels`: one or several distinct finite isovalues.
- :func:`validated_count`, :func:`validated_distance`, :func:`validated_image_size`: options.
"""

from __future__ import annotations

import math

import numpy as np


def validated_shape(shape, *, min_size: int = 1, note: str = "") -> tuple[int, int, int]:
    """``shape`` as three ints ``(nz, ny, nx)``, each at least ``min_size``.

    ``note`` is appended to the message about too few voxels (e.g. how the shape came about).

    Raises
    ------
    ValueError
        If ``shape`` does not have three entries, or an axis has fewer than ``min_size`` voxels (an empty volume
        when ``min_size`` is 1).
    """
    dims = tuple(int(n) for n in shape)
    if len(dims) != 3:
        raise ValueError(f"expected a 3D volume (a real (nz, ny, nx) 3D array), got an array of shape {dims}")
    if min(dims) < max(min_size, 1):
        if min_size <= 1:
            raise ValueError(f"the volume is empty (shape {dims}){note}")
        raise ValueError(f"the volume needs at least {min_size} voxels along every axis (at least {min_size} "
                         f"samples to span a cell), got shape {dims}{note}")
    return dims


def validated_volume(volume, *, min_size: int = 1, finite: bool = False) -> np.ndarray:
    """``volume`` as a 3D boolean or real-valued array (no copy).

    Parameters
    ----------
    volume : array_like, shape (nz, ny, nx)
    min_size : int
        Fewest voxels allowed along an axis (see :func:`validated_shape`).
    finite : bool
        Also reject NaN and infinite values.

    Raises
    ------
    ValueError
        If the array is not 3D, too small, neither boolean nor real-valued, or (with ``finite``) holds NaN or
        infinity.
    """
    array = np.asarray(volume)
    validated_shape(array.shape, min_size=min_size)
    if array.dtype != np.bool_ and array.dtype.kind not in "iuf":
        raise ValueError(f"expected real scalar values: a boolean mask or a real-valued volume, got dtype "
                         f"{array.dtype}")
    if finite and array.dtype.kind == "f" and not np.all(np.isfinite(array)):
        raise ValueError("the volume contains NaN or infinite values")
    return array


def validated_numeric_volume(volume, *, min_size: int = 1, finite: bool = False) -> np.ndarray:
    """:func:`validated_volume`, in the form our numba kernels take: booleans as uint8 (0/1), float16 as float32,
    native byte order, C-contiguous (a copy only where one of these needs it)."""
    array = validated_volume(volume, min_size=min_size, finite=finite)
    if array.dtype == np.bool_:
        array = np.ascontiguousarray(array).view(np.uint8)
    elif array.dtype == np.float16:
        array = array.astype(np.float32)
    return np.ascontiguousarray(array, dtype=array.dtype.newbyteorder("="))


def validated_float_volume(volume) -> np.ndarray:
    """A private, read-only float32 C-ordered copy of a real volume with at least 2 voxels per axis and no NaN or
    infinity (what the software renderers sample: the caller cannot change values a set-up describes)."""
    array = validated_volume(volume, min_size=2)
    copy = np.array(array, dtype=np.float32, order="C", copy=True)
    if array.dtype.kind == "f" and not np.all(np.isfinite(copy)):
        raise ValueError("the volume contains NaN or infinite values")
    copy.setflags(write=False)
    return copy


def validated_solid(volume, threshold=None) -> tuple[np.ndarray, float | None]:
    """A voxel model: ``volume`` as an array and ``threshold`` as a float; the threshold is None for a boolean mask.

    Voxels with ``value >= threshold`` are solid; a boolean mask is solid where True.

    Raises
    ------
    ValueError
        If ``volume`` is not a non-empty 3D boolean or real-valued array, if a scalar volume comes without a
        threshold, if a boolean mask comes with one, or if the threshold is not a finite number.
    """
    array = validated_volume(volume)
    if array.dtype == np.bool_:
        if threshold is not None:
            raise ValueError("a boolean mask is already solid/empty; pass threshold only with a scalar volume")
        return array, None
    if threshold is None:
        raise ValueError("a scalar volume needs a threshold: voxels with value >= threshold are solid")
    try:
        threshold = float(threshold)
    except (TypeError, ValueError):
        raise ValueError(f"threshold must be a number, got {threshold!r}") from None
    if not np.isfinite(threshold):
        raise ValueError(f"threshold must be finite, got {threshold}")
    return array, threshold


def _floats(values) -> np.ndarray | None:
    """``values`` as a float64 array, or None when they are not a sequence of numbers."""
    try:
        return np.array([float(v) for v in values], dtype=np.float64)
    except (TypeError, ValueError):
        return None


def validated_spacing(spacing) -> np.ndarray:
    """``(sx, sy, sz)`` as a float64 array of three positive finite millimetre values."""
    values = _floats(spacing)
    if values is None or values.shape != (3,) or not np.all(np.isfinite(values)) or values.min() <= 0:
        raise ValueError(f"spacing must be three positive millimetre values (x, y, z), got {spacing!r}")
    return values


def validated_origin(origin) -> np.ndarray:
    """``(x, y, z)`` as a float64 array of three finite millimetre values."""
    values = _floats(origin)
    if values is None or values.shape != (3,) or not np.all(np.isfinite(values)):
        raise ValueError(f"origin must be three finite millimetre values (x, y, z), got {origin!r}")
    return values


def validated_geometry(spacing, origin) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """``(spacing, origin)`` as float triples in ``(x, y, z)`` order, checked (positive spacing, finite origin)."""
    if _floats(spacing) is None or _floats(origin) is None:
        raise ValueError(f"spacing and origin must be three numbers each, got {spacing!r} and {origin!r}")
    return tuple(validated_spacing(spacing).tolist()), tuple(validated_origin(origin).tolist())


def validated_levels(level) -> np.ndarray:
    """One isovalue or a sequence of them as a 1D float64 array of distinct finite values."""
    levels = np.atleast_1d(np.asarray(level, dtype=np.float64))
    if levels.ndim != 1 or levels.size == 0:
        raise ValueError(f"give one isovalue or a sequence of isovalues, got {level!r}")
    if not np.all(np.isfinite(levels)):
        raise ValueError(f"isovalues must be finite numbers, got {levels.tolist()}")
    if np.unique(levels).size != levels.size:
        raise ValueError(f"isovalues must be distinct, got {levels.tolist()}")
    return levels


def validated_count(value, name: str, *, note: str = "") -> int:
    """``value`` as a positive int; booleans and fractions are rejected (``note`` explains the option)."""
    whole = isinstance(value, (int, np.integer)) or (
        isinstance(value, (float, np.floating)) and float(value).is_integer())
    if isinstance(value, (bool, np.bool_)) or not whole or value < 1:
        raise ValueError(f"{name} must be a positive integer{note}, got {value!r}")
    return int(value)


def validated_distance(value, name: str) -> float:
    """``value`` as a positive finite float (a length in mm)."""
    try:
        distance = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number of mm, got {value!r}") from None
    if not (math.isfinite(distance) and distance > 0):
        raise ValueError(f"{name} must be a positive number of mm, got {distance}")
    return distance


def validated_image_size(width, height) -> tuple[int, int]:
    """``(width, height)`` of an image as positive whole numbers of pixels."""
    if isinstance(width, bool) or isinstance(height, bool) or int(width) != width or int(height) != height:
        raise ValueError(f"image size must be whole pixels, got {width} x {height}")
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width} x {height}")
    return int(width), int(height)
