"""Helpers the file readers share: axis vectors to spacing and direction, building the Volume, modality hints."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from ..volume import Volume
from .errors import CorruptFileError

LPS_FROM_RAS = np.diag([-1.0, -1.0, 1.0])  # also RAS from LPS: the flip is its own inverse
FLIP4 = np.diag([-1.0, -1.0, 1.0, 1.0])


def orthonormal_direction(axes: np.ndarray, path: Path, warn: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Split a 3x3 matrix whose columns are axis vectors (mm per voxel) into spacing and direction.

    Sheared axes (not perpendicular) are replaced by the nearest orthonormal frame with a warning; zero, infinite
    or NaN axes are a :class:`CorruptFileError`.
    """
    axes = np.asarray(axes, dtype=np.float64)
    if axes.shape != (3, 3) or not np.all(np.isfinite(axes)):
        raise CorruptFileError(path, "the voxel axes (spacing and orientation) are not finite numbers")
    spacing = np.linalg.norm(axes, axis=0)
    if np.any(spacing <= 0) or not np.all(np.isfinite(spacing)):
        raise CorruptFileError(path, f"the voxel axes have zero or invalid length ({spacing.tolist()})")
    direction = axes / spacing
    if abs(np.linalg.det(direction)) < 1e-6:
        raise CorruptFileError(path, "the voxel axes are parallel (the orientation is degenerate)")
    if not np.allclose(direction.T @ direction, np.eye(3), atol=1e-4):
        u, _, vt = np.linalg.svd(direction)
        direction = u @ vt
        warn.append(f"{path.name}: the voxel axes are sheared; the nearest orthogonal orientation is used")
    return spacing, direction


def finite_vector(values, count: int, path: Path, what: str) -> np.ndarray:
    """``count`` finite floats, or a :class:`CorruptFileError` naming the field."""
    try:
        vector = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise CorruptFileError(path, f"{what} is not a list of numbers") from exc
    if vector.shape != (count,) or not np.all(np.isfinite(vector)):
        raise CorruptFileError(path, f"{what} must be {count} finite numbers, got {vector.tolist()[:6]}")
    return vector


def make_volume(array, spacing, origin, direction, path: Path, source_format: str, warn: list[str], modality="",
                units="", extra: dict[str, Any] | None = None):
    """The :class:`app.volume.Volume` of a reader, with ``source_format``, ``source_path`` and warnings."""
    metadata = {"source_format": source_format, "source_path": str(path), "warnings": warn}
    metadata.update(extra or {})
    try:
        return Volume(
            np.ascontiguousarray(array), spacing=tuple(spacing), origin=tuple(origin), direction=direction,
            modality=modality, units=units, metadata=metadata,
        )
    except ValueError as exc:  # the Volume's own validation: spacing, origin, empty data
        raise CorruptFileError(path, f"the image geometry or data is invalid ({exc})") from exc


def modality_from_description(description: str) -> tuple[str, str]:
    """Modality and units that Voxelscope's own writers record in a free-text header field."""
    match = re.search(r"modality=(\w*);units=(\w*)", description or "")
    return (match.group(1), match.group(2)) if match else ("", "")


def guess_ct(array: np.ndarray, warn: list[str], path: Path) -> tuple[str, str]:
    """Integer data spanning air (about -1000) to bone looks like CT in HU; say so instead of guessing silently."""
    if array.dtype.kind not in "iu" or array.size == 0:
        return "", ""
    lo, hi = int(array.min()), int(array.max())
    if -1100 <= lo <= -900 and hi >= 300:
        warn.append(f"{path.name}: values {lo}..{hi} look like CT in Hounsfield units; modality set to CT")
        return "CT", "HU"
    return "", ""
