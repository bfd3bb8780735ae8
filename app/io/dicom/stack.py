"""Stacking 2D images into a volume: duplicates, several volumes in one series, order, pixels, tilt and gaps.

- Exact duplicates (same SOPInstanceUID and frame) are skipped with a warning naming both files.
- A series can hold several volumes at the same positions: echoes, time points, MOSAIC files, enhanced stacks, or
  (GE) volumes told apart only by acquisition order. They are split (:func:`split_volumes`), listed in a warning
  and in ``metadata["volumes"]``, and the first (or the one asked for with ``volume_index``) is loaded. Slices that
  share a position with nothing to tell them apart are refused.
- Slices are ordered by ImagePositionPatient projected on the slice normal (the cross product of the two
  ImageOrientationPatient vectors), never by file name or InstanceNumber; the spacing comes from the positions.
- Gantry tilt (positions that drift in-plane while advancing along the normal) is removed by shifting each slice
  in-plane onto a grid *enlarged* by the drift, so no acquired pixel is dropped (:func:`correct_tilt`).
- Missing slices or uneven spacing (:func:`regularise_spacing`): the stack is resampled by linear interpolation
  along the normal, but at most :data:`MAX_INTERPOLATED_SLICES` consecutive slices are invented; a larger gap is
  refused (naming it in mm) unless the caller allows gaps (``allow_gaps=True``, ``--allow-gaps``). How many slices
  were invented is always reported (``metadata["interpolated_slices"]`` and a warning).
"""

from __future__ import annotations

import math
import re
from collections import Counter, OrderedDict, defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import CorruptFileError, DicomSeriesError, MissingDecoderError
from ..safety import require_fits
from .headers import SliceHeader
from .pixels import decode_pixels, units

#: Tolerance on slice spacing regularity, as a fraction of the median spacing.
SPACING_TOLERANCE = 0.01
#: Gantry tilt below this angle (degrees) is treated as numerical noise.
TILT_TOLERANCE_DEG = 0.05
#: At most this many consecutive missing slices are filled by interpolation without ``allow_gaps``.
MAX_INTERPOLATED_SLICES = 2
#: Positions along the normal closer than this (mm) are the same position.
SAME_POSITION_MM = 0.01


@dataclass
class SliceFrame:
    """The in-plane axes and the slice normal (LPS unit vectors) shared by the slices of a stack."""

    row: np.ndarray
    column: np.ndarray
    normal: np.ndarray

    @classmethod
    def from_orientation(cls, orientation: np.ndarray) -> "SliceFrame":
        row, column = orientation[:3], orientation[3:]
        if np.linalg.norm(row) < 1e-6 or np.linalg.norm(column) < 1e-6:
            raise ValueError("ImageOrientationPatient has a zero vector")
        row, column = row / np.linalg.norm(row), column / np.linalg.norm(column)
        normal = np.cross(row, column)
        if np.linalg.norm(normal) < 1e-3:
            raise ValueError("ImageOrientationPatient's row and column directions are parallel")
        column = np.cross(normal / np.linalg.norm(normal), row)  # re-orthogonalise slightly skewed cosines
        return cls(row, column, normal / np.linalg.norm(normal))

    @property
    def direction(self) -> np.ndarray:
        return np.column_stack([self.row, self.column, self.normal])


@dataclass
class Slices:
    """The pixels of a sorted stack (rescaled), the headers they came from, and the units of the values."""

    array: np.ndarray  # (n, rows, columns)
    headers: list[SliceHeader]
    units: str


def require_geometry(headers: list[SliceHeader]) -> None:
    """Refuse images that cannot be placed in patient space."""
    incomplete = [h for h in headers if h.position is None or h.orientation is None or h.pixel_spacing is None]
    if incomplete:
        raise DicomSeriesError(
            incomplete[0].path,
            "the image lacks ImagePositionPatient, ImageOrientationPatient or PixelSpacing, so slices cannot be placed",
            "Voxelscope needs patient geometry for 3D; this looks like a secondary capture or a 2D image",
        )


def remove_duplicates(headers: list[SliceHeader], warn: list[str]) -> list[SliceHeader]:
    """Drop exact duplicates (same SOPInstanceUID and frame), naming both files."""
    unique: dict[tuple, SliceHeader] = {}
    for header in headers:
        key = (header.sop_uid, header.frame)
        if key in unique:
            if header.frame in (None, 0):
                warn.append(f"{header.path}: skipped, duplicate of {unique[key].path} (same SOPInstanceUID)")
            continue
        unique[key] = header
    return list(unique.values())


# ----------------------------------------------------------------------------------------------------------------
# Several volumes in one series
# ----------------------------------------------------------------------------------------------------------------
def _position_keys(headers: list[SliceHeader], normal: np.ndarray) -> np.ndarray:
    return np.round(np.array([float(h.position @ normal) for h in headers]) / SAME_POSITION_MM).astype(np.int64)


def _distinct(headers: list[SliceHeader], normal: np.ndarray) -> bool:
    keys = _position_keys(headers, normal)
    return len(set(keys.tolist())) == len(keys)


def _natural(value) -> tuple:
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", str(value)))


def split_volumes(headers: list[SliceHeader], normal: np.ndarray) -> tuple[list[list[SliceHeader]], str, list[str]]:
    """Split images sharing positions into volumes: ``(volumes, what tells them apart, a label per volume)``."""
    explicit = [h.volume_key for h in headers]
    if any(k is not None for k in explicit):
        groups: dict = OrderedDict()
        for header in sorted(headers, key=lambda h: (_natural(h.acquisition or ""), h.instance or 0, str(h.path))):
            groups.setdefault(header.volume_key, []).append(header)
        if all(_distinct(g, normal) for g in groups.values()):
            kind = "file" if next(iter(groups))[0] == "file" else "stack"
            labels = [Path(k[1]).name if kind == "file" else str(k[1]) for k in groups]
            return list(groups.values()), kind, labels
    if _distinct(headers, normal):
        return [headers], "", [""]
    for attribute, name in (("echo", "echo number"), ("temporal", "temporal position"),
                            ("acquisition", "acquisition number")):
        groups = defaultdict(list)
        for header in headers:
            groups[getattr(header, attribute)].append(header)
        if len(groups) >= 2 and None not in groups and all(len(g) >= 2 and _distinct(g, normal) for g in groups.values()):
            order = sorted(groups, key=_natural)
            return [groups[v] for v in order], name, [str(v) for v in order]
    # GE and others: volumes told apart only by acquisition order (InstanceNumber) at each position.
    instances = [h.instance for h in headers]
    keys = _position_keys(headers, normal)
    counts = Counter(keys.tolist())
    repeats = set(counts.values())
    if None not in instances and len(set(instances)) == len(instances) and len(repeats) == 1 and repeats != {1}:
        rank: dict[int, int] = defaultdict(int)
        volumes: dict[int, list[SliceHeader]] = defaultdict(list)
        for header, key in sorted(zip(headers, keys.tolist()), key=lambda item: item[0].instance):
            volumes[rank[key]].append(header)
            rank[key] += 1
        return [volumes[v] for v in sorted(volumes)], "acquisition order", [str(v + 1) for v in sorted(volumes)]
    clashes = defaultdict(list)
    for header, key in zip(headers, keys.tolist()):
        clashes[key].append(header.name)
    listed = [f"{key * SAME_POSITION_MM:.3f} mm: {', '.join(names[:4])}" for key, names in clashes.items() if len(names) > 1]
    raise DicomSeriesError(
        headers[0].path.parent,
        f"several slices share the same position along the slice normal ({'; '.join(listed[:3])})",
        "The series mixes volumes Voxelscope cannot tell apart; export one volume per series",
    )


def count_volumes(headers: list[SliceHeader]) -> int:
    """How many volumes a stack holds (0 when they cannot be told apart or placed)."""
    try:
        require_geometry(headers)
        frame = SliceFrame.from_orientation(headers[0].orientation)
        return len(split_volumes(headers, frame.normal)[0])
    except (DicomSeriesError, ValueError):
        return 0


def choose_volume(headers: list[SliceHeader], normal: np.ndarray, volume_index: int | None, warn: list[str],
                  metadata: dict) -> list[SliceHeader]:
    """The headers of one volume of the stack; lists the others in ``warn`` and ``metadata["volumes"]``."""
    volumes, kind, labels = split_volumes(headers, normal)
    index = 0 if volume_index is None else int(volume_index)
    if not 0 <= index < len(volumes):
        raise DicomSeriesError(headers[0].path.parent, f"volume {index} was asked for, but the series holds "
                                                       f"{len(volumes)} volume(s)",
                               f"Choose a volume from 0 to {len(volumes) - 1}")
    if len(volumes) > 1:
        metadata["volumes"] = [{"index": i, kind: label, "slices": len(v)} for i, (label, v) in
                               enumerate(zip(labels, volumes))]
        metadata["volume_index"] = index
        shown = ", ".join(labels[:12]) + (", ..." if len(labels) > 12 else "")
        warn.append(f"the series holds {len(volumes)} volumes ({kind}s {shown}); loaded {kind} {labels[index]} "
                    f"({len(volumes[index])} slices); choose another with volume_index (--volume N)")
    return volumes[index]


# ----------------------------------------------------------------------------------------------------------------
# Pixels
# ----------------------------------------------------------------------------------------------------------------
def read_slices(headers: list[SliceHeader], folder: Path, modality: str, warn: list[str],
                progress: Callable[[float], None] | None = None) -> Slices:
    """Decode and rescale each image, skipping damaged files (reported by name); at least two must remain."""
    require_fits(folder, len(headers) * headers[0].rows * headers[0].columns * 8, "the image stack")
    decoded: OrderedDict[Path, tuple] = OrderedDict()
    failed: dict[Path, str] = {}
    notes: list[str] = []
    slices, kept = [], []
    value_units = ""
    for index, header in enumerate(headers):
        if progress is not None:
            progress(index / len(headers))
        if header.path in failed:
            continue
        if header.path not in decoded:
            try:
                file_notes: list[str] = []
                decoded[header.path] = decode_pixels(header.path, notes=file_notes)
                notes.extend(f"{header.path}: pydicom: {n}" for n in file_notes[:3])
            except MissingDecoderError:
                raise
            except CorruptFileError as exc:
                failed[header.path] = exc.problem
                warn.append(f"{header.path}: skipped, {exc.problem}")
                continue
            while len(decoded) > 2:
                decoded.popitem(last=False)
        pixels, dataset = decoded[header.path]
        image = _frame_pixels(pixels, header)
        if image is None:
            failed[header.path] = "wrong pixel array"
            warn.append(f"{header.path}: skipped, pixel array of shape {pixels.shape} (expected grey-level frames of "
                        f"{header.rows}x{header.columns})")
            continue
        if (header.slope, header.intercept) != (1.0, 0.0):
            image = image.astype(np.float64) * header.slope + header.intercept
        value_units = units(dataset, modality)
        slices.append(image)
        kept.append(header)
    warn.extend(dict.fromkeys(notes))
    if len(kept) < 2:
        files = {h.path for h in headers}
        if len(files) == 1 and failed:  # one multi-frame or MOSAIC file: its own error says it best
            only = next(iter(files))
            raise CorruptFileError(only, failed[only], "Re-export or re-copy it")
        raise DicomSeriesError(folder, "fewer than two slices of the series could be read", "; ".join(warn[:3]))
    dtype = np.float64 if any(s.dtype.kind == "f" for s in slices) else np.result_type(*{s.dtype for s in slices})
    return Slices(np.stack(slices).astype(dtype, copy=False), kept, value_units)


def _frame_pixels(pixels: np.ndarray, header: SliceHeader) -> np.ndarray | None:
    if header.mosaic is not None:
        image = header.mosaic.tile(pixels) if pixels.ndim == 2 else None
    elif header.frames > 1 and header.frame is not None:
        image = pixels[header.frame] if pixels.ndim == 3 and header.frame < pixels.shape[0] else None
    else:
        image = pixels if pixels.ndim == 2 else None
    if image is None or image.shape != (header.rows, header.columns):
        return None
    return image


# ----------------------------------------------------------------------------------------------------------------
# Geometry: gantry tilt and gaps
# ----------------------------------------------------------------------------------------------------------------
def correct_tilt(array: np.ndarray, positions: np.ndarray, frame: SliceFrame, pixel_spacing, warn: list[str]):
    """Remove the shear of a gantry-tilted stack onto an enlarged grid.

    Returns ``(array, origin, tilt_deg)``: each slice moved in-plane by its drift (linear interpolation for the
    fractional part) into a grid grown by the total drift, so every acquired pixel is kept; ``origin`` is the
    LPS position of the new voxel (0, 0, 0).
    """
    along = positions @ frame.normal
    drift = positions - positions[0] - np.outer(along - along[0], frame.normal)
    length = float(along[-1] - along[0])
    tilt_deg = math.degrees(math.atan2(float(np.max(np.linalg.norm(drift, axis=1))), abs(length))) if length else 0.0
    if tilt_deg <= TILT_TOLERANCE_DEG:
        return array, positions[0], tilt_deg
    from scipy import ndimage

    spacing_i, spacing_j = pixel_spacing[1], pixel_spacing[0]
    shift_i = drift @ frame.row / spacing_i  # pixels along columns (i)
    shift_j = drift @ frame.column / spacing_j  # pixels along rows (j)
    low_i, low_j = math.floor(shift_i.min() + 1e-6), math.floor(shift_j.min() + 1e-6)
    grow_i = math.ceil(shift_i.max() - 1e-6) - low_i
    grow_j = math.ceil(shift_j.max() - 1e-6) - low_j
    n, rows, columns = array.shape
    require_fits(Path("."), n * (rows + grow_j) * (columns + grow_i) * 8, "the tilt-corrected stack")
    fill = float(array.min())
    corrected = np.full((n, rows + grow_j, columns + grow_i), fill, dtype=np.float64)
    for k in range(n):
        whole_j, whole_i = math.floor(shift_j[k] - low_j + 1e-6), math.floor(shift_i[k] - low_i + 1e-6)
        part_j, part_i = shift_j[k] - low_j - whole_j, shift_i[k] - low_i - whole_i
        image = array[k].astype(np.float64)
        if abs(part_j) > 1e-6 or abs(part_i) > 1e-6:  # fractional part: pad one pixel so nothing falls off
            padded = np.pad(image, ((0, 1), (0, 1)), constant_values=fill)
            image = ndimage.shift(padded, (part_j, part_i), order=1, mode="grid-constant", cval=fill)
        height = min(image.shape[0], corrected.shape[1] - whole_j)
        width = min(image.shape[1], corrected.shape[2] - whole_i)
        corrected[k, whole_j:whole_j + height, whole_i:whole_i + width] = image[:height, :width]
    origin = positions[0] + low_i * spacing_i * frame.row + low_j * spacing_j * frame.column
    warn.append(
        f"gantry tilt of {tilt_deg:.2f} degrees detected; each slice was shifted in-plane (linear interpolation) "
        f"onto a grid enlarged by {grow_i}x{grow_j} pixels, so no acquired pixel is lost"
    )
    return corrected, origin, tilt_deg


def regularise_spacing(array: np.ndarray, along: np.ndarray, names: list[str], folder: Path, irregular: str,
                       allow_gaps: bool, warn: list[str]) -> tuple[np.ndarray, float, int]:
    """The slice spacing and the stack on a regular grid; returns ``(array, spacing, invented slices)``."""
    steps = np.diff(along)
    spacing_k = float(np.median(steps))
    if spacing_k <= 0:
        raise DicomSeriesError(folder, "all slices lie at the same position", "The series cannot form a volume")
    irregular_steps = np.abs(steps - spacing_k) > SPACING_TOLERANCE * spacing_k
    if not np.any(irregular_steps):
        return array, spacing_k, 0
    gaps = [
        f"{along[i]:.2f} to {along[i + 1]:.2f} mm ({steps[i]:.2f} mm, {names[i]} -> {names[i + 1]})"
        for i in np.nonzero(irregular_steps)[0][:4]
    ]
    ratios = steps / spacing_k
    missing = int(round(float(np.sum(np.maximum(np.round(ratios) - 1, 0)))))
    description = (f"{missing} slice(s) missing" if missing and np.allclose(ratios, np.round(ratios), atol=0.05)
                   else "irregular slice spacing")
    if irregular == "error":
        raise DicomSeriesError(
            folder,
            f"{description}: spacing is {spacing_k:.3f} mm but gaps differ at {'; '.join(gaps)}",
            "Re-export the complete series, or load with resampling to fill the gaps by interpolation",
        )
    count = int(round((along[-1] - along[0]) / spacing_k)) + 1
    targets = along[0] + np.arange(count) * spacing_k
    upper = np.clip(np.searchsorted(along, targets, side="right"), 1, len(along) - 1)
    lower = upper - 1
    nearest = np.minimum(np.abs(targets - along[lower]), np.abs(along[upper] - targets))
    invented = nearest > 0.25 * spacing_k
    longest, run = 0, 0
    for flag in invented:
        run = run + 1 if flag else 0
        longest = max(longest, run)
    if longest > MAX_INTERPOLATED_SLICES and not allow_gaps:
        widest = int(np.argmax(steps))
        raise DicomSeriesError(
            folder,
            f"a gap of {steps[widest]:.1f} mm between the slices at {along[widest]:.2f} and {along[widest + 1]:.2f} mm "
            f"({names[widest]} -> {names[widest + 1]}) would need {longest} consecutive slices invented at "
            f"{spacing_k:.3f} mm spacing; Voxelscope interpolates at most {MAX_INTERPOLATED_SLICES}",
            "Re-export the complete series, or load with --allow-gaps (allow_gaps=True) to interpolate across it",
        )
    require_fits(folder, count * array.shape[1] * array.shape[2] * 8, "the resampled stack")
    weight = np.clip((targets - along[lower]) / (along[upper] - along[lower]), 0.0, 1.0)[:, None, None]
    array = array[lower] * (1 - weight) + array[upper] * weight
    made = int(np.count_nonzero(invented))
    warn.append(
        f"{description} at {'; '.join(gaps)}; resampled to {count} slices at {spacing_k:.3f} mm by linear "
        f"interpolation along the stack; {made} slice(s) invented by interpolation"
    )
    return array, spacing_k, made
