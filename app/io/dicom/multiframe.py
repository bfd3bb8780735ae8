"""Multi-frame DICOM files.

- *Enhanced* CT/MR/PET objects (and Siemens XA "enhanced" exports, one or many frames per file) describe each
  frame in functional groups: position (PlanePositionSequence), orientation (PlaneOrientationSequence), pixel
  spacing (PixelMeasuresSequence), rescale (PixelValueTransformationSequence), and which volume it belongs to
  (FrameContentSequence: temporal position, stack; MREchoSequence: echo time). :func:`enhanced_frames` turns such
  a file into one :class:`SliceHeader` per frame, so a folder of enhanced files (or one file holding several
  volumes) stacks exactly like single-frame slices.
- *Legacy* multi-frame files (RT dose, NM) have one position and a ``GridFrameOffsetVector`` or a slice spacing:
  :func:`read_multiframe` reads them as a volume.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ...volume import Volume
from ..errors import CorruptFileError, DicomSeriesError
from .headers import ElementError, SliceHeader, element, float_list, number, rescale, study_fields, text, vector
from .pixels import decode_pixels, store, units

#: Tolerance on frame spacing regularity of legacy multi-frame files, as a fraction of the median spacing.
SPACING_TOLERANCE = 0.01


def sequence_item(dataset, *names):
    """Follow nested single-item sequences: ``sequence_item(ds, 'SharedFunctionalGroupsSequence', ...)``."""
    item = dataset
    for name in names:
        sequence = element(item, name) if item is not None else None
        if not sequence:
            return None
        item = sequence[0]
    return item


def is_enhanced(dataset) -> bool:
    """True for files that describe their frames in functional groups."""
    return "PerFrameFunctionalGroupsSequence" in dataset or "SharedFunctionalGroupsSequence" in dataset


class _Groups:
    """Looks up an attribute for a frame: per-frame functional group first, then shared, then the top level."""

    def __init__(self, dataset) -> None:
        self.dataset = dataset
        self.per_frame = element(dataset, "PerFrameFunctionalGroupsSequence") or []
        shared = element(dataset, "SharedFunctionalGroupsSequence")
        self.shared = shared[0] if shared else None

    def item(self, frame: int, sequence: str):
        if frame < len(self.per_frame):
            found = sequence_item(self.per_frame[frame], sequence)
            if found is not None:
                return found
        return sequence_item(self.shared, sequence) if self.shared is not None else None

    def vector(self, frame: int, sequence: str, keyword: str, count: int):
        found = self.item(frame, sequence)
        value = vector(found, keyword, count) if found is not None and keyword in found else None
        return value if value is not None else vector(self.dataset, keyword, count)

    def value(self, frame: int, sequence: str, keyword: str):
        found = self.item(frame, sequence)
        return text(found, keyword) if found is not None and keyword in found else None


def enhanced_frames(header: SliceHeader, dataset) -> list[SliceHeader]:
    """One header per frame of an enhanced multi-frame file (see the module notes)."""
    groups = _Groups(dataset)
    if groups.per_frame and len(groups.per_frame) != header.frames:
        raise ElementError(f"PerFrameFunctionalGroupsSequence has {len(groups.per_frame)} items for "
                           f"NumberOfFrames {header.frames}")
    frames = []
    for index in range(header.frames):
        spacing = groups.vector(index, "PixelMeasuresSequence", "PixelSpacing", 2)
        transform = groups.item(index, "PixelValueTransformationSequence")
        slope, intercept = rescale(transform) if transform is not None else (header.slope, header.intercept)
        temporal = groups.value(index, "FrameContentSequence", "TemporalPositionIndex")
        stack = groups.value(index, "FrameContentSequence", "StackID")
        echo = groups.value(index, "MREchoSequence", "EffectiveEchoTime")
        frames.append(replace(
            header,
            position=groups.vector(index, "PlanePositionSequence", "ImagePositionPatient", 3),
            orientation=groups.vector(index, "PlaneOrientationSequence", "ImageOrientationPatient", 6),
            pixel_spacing=None if spacing is None else (float(spacing[0]), float(spacing[1])),
            slope=slope, intercept=intercept, frame=index,
            echo=echo or header.echo, temporal=temporal or header.temporal,
            volume_key=None if stack is None else ("stack", stack),
        ))
    return frames


def read_multiframe(path):
    """Read a legacy multi-frame DICOM file (RT dose, NM, ...) as a volume."""
    path = Path(path)
    pixels, dataset = decode_pixels(path)
    try:
        frames = number(dataset, "NumberOfFrames", 1, kind=int)
        orientation = vector(dataset, "ImageOrientationPatient", 6)
        pixel_spacing = vector(dataset, "PixelSpacing", 2)
        first = vector(dataset, "ImagePositionPatient", 3)
        offsets = element(dataset, "GridFrameOffsetVector")
        step = number(dataset, "SpacingBetweenSlices", 0.0) or number(dataset, "SliceThickness", 0.0) or 0.0
        slope, intercept = rescale(dataset)
        scaling = number(dataset, "DoseGridScaling", 1.0) if text(dataset, "Modality") == "RTDOSE" else 1.0
    except ElementError as exc:
        raise CorruptFileError(path, str(exc)) from exc
    if pixels.ndim != 3 or pixels.shape[0] != frames:
        raise CorruptFileError(
            path, f"expected {frames} grey-level frames, got a pixel array of shape {pixels.shape}",
            "Colour or single-frame images cannot be read as a volume",
        )
    if orientation is None or pixel_spacing is None:
        raise DicomSeriesError(
            path, "the multi-frame image lacks orientation or pixel spacing", "It cannot be placed in patient space"
        )
    warn: list[str] = []
    row_cos, col_cos = orientation[:3] / np.linalg.norm(orientation[:3]), orientation[3:] / np.linalg.norm(orientation[3:])
    normal = np.cross(row_cos, col_cos)
    normal /= np.linalg.norm(normal)
    if first is None:
        raise DicomSeriesError(path, "the multi-frame image has no frame positions", "It cannot be placed in space")
    offsets = float_list(offsets, frames) if offsets is not None else None
    if offsets is not None:
        positions = first + np.outer(offsets, normal)
    else:
        if step <= 0:
            raise DicomSeriesError(path, "no frame positions, offsets or slice spacing", "It cannot be stacked")
        positions = first + np.outer(np.arange(frames) * step, normal)
        warn.append(f"{path.name}: frame positions taken from SpacingBetweenSlices/SliceThickness ({step} mm)")
    values = pixels.astype(np.float64) * (slope * scaling) + intercept
    along = positions @ normal
    order = np.argsort(along, kind="stable")
    values, positions, along = values[order], positions[order], along[order]
    steps = np.diff(along)
    if len(steps) == 0 or np.median(steps) <= 0:
        raise DicomSeriesError(path, "the frames do not advance along the slice normal", "It cannot form a volume")
    spacing_k = float(np.median(steps))
    if np.any(np.abs(steps - spacing_k) > SPACING_TOLERANCE * spacing_k):
        raise DicomSeriesError(
            path, f"frame spacing is irregular ({steps.min():.3f} to {steps.max():.3f} mm)",
            "Voxelscope does not resample multi-frame files; export as a regular series",
        )
    modality = text(dataset, "Modality")
    metadata = {
        "source_format": "DICOM multi-frame",
        "source_path": str(path),
        "series_uid": text(dataset, "SeriesInstanceUID"),
        "series_description": text(dataset, "SeriesDescription"),
        "files_used": 1,
        "other_series": [],
        "warnings": warn,
        "dicom": study_fields(Path(path)),
    }
    return Volume(
        store(values) if modality != "RTDOSE" else values.astype(np.float32),
        spacing=(float(pixel_spacing[1]), float(pixel_spacing[0]), spacing_k),
        origin=tuple(positions[0]),
        direction=np.column_stack([row_cos, col_cos, normal]),
        modality=modality,
        units="Gy" if modality == "RTDOSE" else units(dataset, modality),
        metadata=metadata,
    )
