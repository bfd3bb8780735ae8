"""DICOM series and multi-frame readers (pydicom).

What a real scanner folder needs, and what this module does about it:

- Files are grouped by SeriesInstanceUID, then by image geometry (size and orientation), so a localizer (scout)
  saved in the same series or folder never ends up in the stack. The largest stack is chosen unless the caller
  names a series; the others are listed with the reason they were not used.
- Headers are read first with ``stop_before_pixels`` (fast on large series); pixels only for the chosen stack.
- Slices are ordered by ImagePositionPatient projected on the slice normal (the cross product of the two
  ImageOrientationPatient vectors), never by file name or InstanceNumber.
- Slice spacing comes from the positions. Missing slices or irregular spacing are detected and reported; the
  volume is then resampled to regular spacing by linear interpolation along the stack (``irregular="resample"``,
  the default) or refused (``irregular="error"``).
- Gantry tilt (positions that do not advance along the normal) is detected and the shear removed by shifting each
  slice in-plane, with a warning stating the angle.
- RescaleSlope/RescaleIntercept are applied per slice (CT in Hounsfield units).
- Unreadable, truncated or non-DICOM files are skipped with a warning that names them.
- Compressed transfer syntaxes are decoded by pydicom's plugins (pylibjpeg, pillow); when none can, a
  :class:`MissingDecoderError` names the syntax and the package to install.
"""

from __future__ import annotations

import math
import os
import warnings
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .errors import CorruptFileError, DicomSeriesError, MissingDecoderError

#: Tolerance on slice spacing regularity, as a fraction of the median spacing.
SPACING_TOLERANCE = 0.01
#: Gantry tilt below this angle (degrees) is treated as numerical noise.
TILT_TOLERANCE_DEG = 0.05

_DECODER_HINTS = {
    "1.2.840.10008.1.2.4.50": "pillow or pylibjpeg-libjpeg",
    "1.2.840.10008.1.2.4.51": "pylibjpeg-libjpeg",
    "1.2.840.10008.1.2.4.57": "pylibjpeg-libjpeg",
    "1.2.840.10008.1.2.4.70": "pylibjpeg-libjpeg",
    "1.2.840.10008.1.2.4.80": "pylibjpeg-libjpeg",
    "1.2.840.10008.1.2.4.81": "pylibjpeg-libjpeg",
    "1.2.840.10008.1.2.4.90": "pylibjpeg-openjpeg",
    "1.2.840.10008.1.2.4.91": "pylibjpeg-openjpeg",
    "1.2.840.10008.1.2.4.201": "pylibjpeg-openjpeg",
    "1.2.840.10008.1.2.4.202": "pylibjpeg-openjpeg",
    "1.2.840.10008.1.2.4.203": "pylibjpeg-openjpeg",
}


def _pydicom():
    import pydicom

    return pydicom


# ----------------------------------------------------------------------------------------------------------------
# Scanning
# ----------------------------------------------------------------------------------------------------------------
@dataclass
class SliceHeader:
    """What the reader needs from one file's header."""

    path: Path
    series_uid: str
    sop_uid: str
    rows: int
    columns: int
    position: np.ndarray | None
    orientation: np.ndarray | None  # (6,): row cosines then column cosines
    pixel_spacing: tuple[float, float] | None  # (between rows, between columns)
    frames: int
    modality: str
    description: str
    image_type: str
    echo: Any
    temporal: Any

    @property
    def geometry_key(self) -> tuple:
        orientation = None if self.orientation is None else tuple(np.round(self.orientation, 3))
        return (self.series_uid, self.rows, self.columns, orientation)


@dataclass
class SeriesInfo:
    """One stack candidate in a folder: a series (or part of one with a common geometry)."""

    series_uid: str
    description: str
    modality: str
    rows: int
    columns: int
    files: list[Path] = field(default_factory=list)
    headers: list[SliceHeader] = field(default_factory=list)

    @property
    def size(self) -> int:
        return len(self.headers)

    def summary(self) -> dict[str, Any]:
        return {
            "series_uid": self.series_uid,
            "description": self.description,
            "modality": self.modality,
            "slices": self.size,
            "rows": self.rows,
            "columns": self.columns,
        }


@dataclass
class FolderScan:
    """The result of scanning a folder: image series candidates and files skipped with reasons."""

    folder: Path
    series: list[SeriesInfo]
    skipped: list[tuple[Path, str]]

    def warnings(self) -> list[str]:
        return [f"{path}: skipped, {reason}" for path, reason in self.skipped]


def _float_list(value, count: int) -> np.ndarray | None:
    if value is None:
        return None
    try:
        array = np.array([float(v) for v in value], dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return array if array.shape == (count,) and np.all(np.isfinite(array)) else None


def read_header(path: Path):
    """Read a DICOM header without pixels; raises ``InvalidDicomError`` for non-DICOM files."""
    pydicom = _pydicom()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return pydicom.dcmread(path, stop_before_pixels=True)
        except pydicom.errors.InvalidDicomError:
            # Files without the 128-byte preamble ("raw" DICOM from some PACS exports): accept them only if a
            # forced parse finds an SOP class, so random files are not misread as DICOM.
            dataset = pydicom.dcmread(path, stop_before_pixels=True, force=True)
            if "SOPClassUID" not in dataset:
                raise
            return dataset


def _slice_header(path: Path, dataset) -> SliceHeader:
    spacing = _float_list(dataset.get("PixelSpacing"), 2)
    image_type = "\\".join(str(v) for v in dataset.get("ImageType", []) or [])
    return SliceHeader(
        path=path,
        series_uid=str(dataset.get("SeriesInstanceUID", "") or "unknown-series"),
        sop_uid=str(dataset.get("SOPInstanceUID", "") or path.name),
        rows=int(dataset.get("Rows", 0) or 0),
        columns=int(dataset.get("Columns", 0) or 0),
        position=_float_list(dataset.get("ImagePositionPatient"), 3),
        orientation=_float_list(dataset.get("ImageOrientationPatient"), 6),
        pixel_spacing=None if spacing is None else (float(spacing[0]), float(spacing[1])),
        frames=int(dataset.get("NumberOfFrames", 1) or 1),
        modality=str(dataset.get("Modality", "") or ""),
        description=str(dataset.get("SeriesDescription", "") or ""),
        image_type=image_type,
        echo=dataset.get("EchoNumbers"),
        temporal=dataset.get("TemporalPositionIdentifier"),
    )


def _iter_files(folder: Path) -> list[Path]:
    files = []
    for root, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(names):
            if name.startswith(".") or name.upper() == "DICOMDIR":
                continue
            files.append(Path(root) / name)
    return files


def scan_folder(folder, progress: Callable[[float], None] | None = None) -> FolderScan:
    """Read every file's header in ``folder`` (recursively) and group the images into stack candidates."""
    pydicom = _pydicom()
    folder = Path(folder)
    files = _iter_files(folder)
    if not files:
        raise DicomSeriesError(folder, "the folder contains no files", "Choose the folder that holds the DICOM series")
    groups: dict[tuple, SeriesInfo] = {}
    skipped: list[tuple[Path, str]] = []
    for index, path in enumerate(files):
        if progress is not None and index % 32 == 0:
            progress(index / len(files))
        try:
            dataset = read_header(path)
        except pydicom.errors.InvalidDicomError:
            skipped.append((path, "not a DICOM file"))
            continue
        except (EOFError, OSError, ValueError, TypeError, AttributeError, KeyError) as exc:
            skipped.append((path, f"unreadable or truncated DICOM header ({type(exc).__name__}: {exc})"))
            continue
        header = _slice_header(path, dataset)
        if header.rows <= 0 or header.columns <= 0:
            skipped.append((path, f"no image in this object (Modality {header.modality or 'unknown'})"))
            continue
        key = header.geometry_key
        if key not in groups:
            groups[key] = SeriesInfo(header.series_uid, header.description, header.modality, header.rows, header.columns)
        groups[key].headers.append(header)
        groups[key].files.append(path)
    series = sorted(groups.values(), key=lambda s: (-s.size, s.series_uid))
    if progress is not None:
        progress(1.0)
    return FolderScan(folder, series, skipped)


# ----------------------------------------------------------------------------------------------------------------
# Pixels
# ----------------------------------------------------------------------------------------------------------------
def _transfer_syntax(dataset) -> tuple[str, str]:
    meta = getattr(dataset, "file_meta", None)
    uid = meta.get("TransferSyntaxUID") if meta is not None else None
    if uid is None:
        return "", "unknown transfer syntax"
    return str(uid), getattr(uid, "name", str(uid))


def decode_pixels(path: Path, dataset=None) -> tuple[np.ndarray, Any]:
    """Read a file fully and return its pixel array and dataset.

    Raises :class:`CorruptFileError` for truncated or damaged pixel data and :class:`MissingDecoderError` when
    the transfer syntax cannot be decoded with the installed plugins.
    """
    pydicom = _pydicom()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if dataset is None or "PixelData" not in dataset:
                dataset = pydicom.dcmread(path, force=True)
    except (EOFError, OSError, ValueError) as exc:
        raise CorruptFileError(path, f"the file is unreadable or truncated ({exc})", "Re-export or re-copy it") from exc
    if "PixelData" not in dataset:
        raise CorruptFileError(path, "the file has no pixel data (it may be truncated)", "Re-export or re-copy it")
    uid, name = _transfer_syntax(dataset)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pixels = dataset.pixel_array
    except (NotImplementedError, RuntimeError) as exc:
        text = str(exc)
        compressed = bool(uid) and uid not in ("1.2.840.10008.1.2", "1.2.840.10008.1.2.1", "1.2.840.10008.1.2.2",
                                               "1.2.840.10008.1.2.1.99")
        if compressed and ("plugin" in text or "decod" in text.lower() or "handler" in text):
            package = _DECODER_HINTS.get(uid)
            hint = (f"Install {package} into Voxelscope's environment, or convert the series to uncompressed DICOM"
                    if package else "No decoder for this syntax is available to pydicom; convert the series to "
                                    "uncompressed DICOM (for example on the PACS) and open it again")
            raise MissingDecoderError(
                path,
                f"the pixel data is compressed as '{name}' ({uid}) and no installed decoder could read it "
                f"({text.splitlines()[0]})",
                hint,
            ) from exc
        raise CorruptFileError(path, f"the pixel data could not be decoded ({text.splitlines()[0]})") from exc
    except (ValueError, AttributeError, KeyError, TypeError) as exc:
        raise CorruptFileError(
            path, f"the pixel data is damaged or truncated ({str(exc).splitlines()[0]})", "Re-export or re-copy the file"
        ) from exc
    return np.asarray(pixels), dataset


def _rescale(dataset) -> tuple[float, float]:
    slope = dataset.get("RescaleSlope", 1)
    intercept = dataset.get("RescaleIntercept", 0)
    try:
        return float(slope if slope not in (None, "") else 1), float(intercept if intercept not in (None, "") else 0)
    except (TypeError, ValueError):
        return 1.0, 0.0


def _units(dataset, modality: str) -> str:
    """Units of the rescaled values: RescaleType when given (HU, ...), HU for CT, none otherwise."""
    rescale_type = str(dataset.get("RescaleType", "") or "").upper()
    if rescale_type == "HU" or (modality == "CT" and rescale_type in ("", "US")):
        return "HU"
    if rescale_type and rescale_type != "US":  # US = unspecified
        return rescale_type
    return ""


def _store(values: np.ndarray) -> np.ndarray:
    """Keep integers as int16/int32 when the rescaled values are whole numbers; otherwise float32."""
    if values.dtype.kind in "iu":
        lo, hi = int(values.min()), int(values.max())
        if -32768 <= lo and hi <= 32767:
            return values.astype(np.int16)
        return values.astype(np.int32)
    if np.all(np.isfinite(values)) and np.array_equal(values, np.round(values)):
        lo, hi = values.min(), values.max()
        if -32768 <= lo and hi <= 32767:
            return values.astype(np.int16)
    return values.astype(np.float32)


# ----------------------------------------------------------------------------------------------------------------
# Stacking a single-frame series
# ----------------------------------------------------------------------------------------------------------------
def _describe_series(series: SeriesInfo) -> str:
    label = series.description or "no description"
    return f"series {series.series_uid} ({label}, {series.modality or 'unknown modality'}, {series.size} images of {series.columns}x{series.rows})"


def _choose_series(scan: FolderScan, series_uid: str | None) -> tuple[SeriesInfo, list[dict[str, Any]]]:
    candidates = [s for s in scan.series if s.size > 0]
    if not candidates:
        reasons = "; ".join(f"{p.name}: {r}" for p, r in scan.skipped[:5])
        raise DicomSeriesError(
            scan.folder,
            "no DICOM images found" + (f" ({len(scan.skipped)} files skipped: {reasons})" if scan.skipped else ""),
            "Choose a folder that holds a CT or MR image series",
        )
    if series_uid is not None:
        matching = [s for s in candidates if s.series_uid == series_uid]
        if not matching:
            available = ", ".join(f"{s.series_uid} ({s.size} images)" for s in candidates)
            raise DicomSeriesError(scan.folder, f"no series with UID {series_uid}", f"Available series: {available}")
        chosen = matching[0]
    else:
        chosen = candidates[0]
    others = []
    for series in candidates:
        if series is chosen:
            continue
        if series.series_uid == chosen.series_uid:
            reason = "same series but a different image size or orientation (e.g. a localizer)"
        elif series.size < chosen.size:
            reason = "a smaller stack than the chosen series"
        else:
            reason = "not the series asked for"
        others.append({**series.summary(), "reason": reason})
    return chosen, others


def _resolve_duplicates(headers: list[SliceHeader], normal: np.ndarray, warn: list[str]) -> list[SliceHeader]:
    """Drop exact duplicate files; split several volumes sharing positions (echoes, time points) and keep the first."""
    unique: dict[str, SliceHeader] = {}
    for header in headers:
        if header.sop_uid in unique:
            warn.append(f"{header.path}: skipped, duplicate of {unique[header.sop_uid].path} (same SOPInstanceUID)")
            continue
        unique[header.sop_uid] = header
    headers = list(unique.values())
    positions = np.round([float(h.position @ normal) for h in headers], 3)
    if len(set(positions)) == len(positions):
        return headers
    for attribute in ("echo", "temporal"):
        values = [getattr(h, attribute) for h in headers]
        distinct = sorted({str(v) for v in values if v is not None})
        if len(distinct) > 1:
            first = distinct[0]
            kept = [h for h in headers if str(getattr(h, attribute)) == first]
            kept_positions = np.round([float(h.position @ normal) for h in kept], 3)
            if len(set(kept_positions)) == len(kept_positions):
                name = "echo number" if attribute == "echo" else "temporal position"
                warn.append(
                    f"the series holds {len(distinct)} volumes ({name}s {', '.join(distinct)}); "
                    f"loaded {name} {first} ({len(kept)} slices)"
                )
                return kept
    counts = defaultdict(list)
    for header, position in zip(headers, positions):
        counts[position].append(header.path.name)
    clashes = [f"{pos:.3f} mm: {', '.join(names)}" for pos, names in counts.items() if len(names) > 1][:3]
    raise DicomSeriesError(
        headers[0].path.parent,
        f"several slices share the same position along the slice normal ({'; '.join(clashes)})",
        "The series mixes volumes Voxelscope cannot tell apart; export one volume per series",
    )


def read_dicom_series(
    folder,
    *,
    series_uid: str | None = None,
    irregular: str = "resample",
    progress: Callable[[float], None] | None = None,
):
    """Read the image series in ``folder`` into a :class:`app.volume.Volume`.

    Parameters
    ----------
    folder : path
        A folder with the files of one or more series (searched recursively).
    series_uid : str, optional
        SeriesInstanceUID to load; default: the largest stack.
    irregular : {"resample", "error"}
        What to do with missing slices or uneven spacing.
    progress : callable, optional
        Called with a fraction in [0, 1].
    """
    from ..volume import Volume

    if irregular not in ("resample", "error"):
        raise ValueError(f"irregular must be 'resample' or 'error', got {irregular!r}")
    folder = Path(folder)
    scan = scan_folder(folder, progress=None if progress is None else (lambda f: progress(0.3 * f)))
    warn = scan.warnings()
    chosen, others = _choose_series(scan, series_uid)

    if len(chosen.headers) == 1 and chosen.headers[0].frames > 1:
        volume = read_multiframe(chosen.headers[0].path)
        volume.metadata["warnings"] = warn + volume.metadata.get("warnings", [])
        volume.metadata["other_series"] = others
        return volume

    incomplete = [h for h in chosen.headers if h.position is None or h.orientation is None or h.pixel_spacing is None]
    if incomplete:
        raise DicomSeriesError(
            incomplete[0].path,
            "the image lacks ImagePositionPatient, ImageOrientationPatient or PixelSpacing, so slices cannot be placed",
            "Voxelscope needs patient geometry for 3D; this looks like a secondary capture or a 2D image",
        )
    orientation = chosen.headers[0].orientation
    row_cos, col_cos = orientation[:3], orientation[3:]
    row_cos, col_cos = row_cos / np.linalg.norm(row_cos), col_cos / np.linalg.norm(col_cos)
    normal = np.cross(row_cos, col_cos)
    normal /= np.linalg.norm(normal)
    headers = _resolve_duplicates(chosen.headers, normal, warn)
    if len(headers) < 2:
        raise DicomSeriesError(
            folder,
            f"the chosen series has a single slice ({headers[0].path.name}); a volume needs at least two",
            "Check that the whole series was copied",
        )
    headers.sort(key=lambda h: float(h.position @ normal))

    # Pixels, slice by slice, skipping damaged files (reported by name).
    slices, kept = [], []
    units = ""
    modality = chosen.modality
    for index, header in enumerate(headers):
        if progress is not None:
            progress(0.3 + 0.6 * index / len(headers))
        try:
            pixels, dataset = decode_pixels(header.path)
        except MissingDecoderError:
            raise
        except CorruptFileError as exc:
            warn.append(f"{header.path}: skipped, {exc.problem}")
            continue
        if pixels.shape != (header.rows, header.columns):
            warn.append(f"{header.path}: skipped, pixel array of shape {pixels.shape} (expected one grey-level frame)")
            continue
        slope, intercept = _rescale(dataset)
        values = pixels.astype(np.float64) * slope + intercept if (slope, intercept) != (1.0, 0.0) else pixels
        units = _units(dataset, modality)
        slices.append(values)
        kept.append(header)
    if len(kept) < 2:
        raise DicomSeriesError(folder, "fewer than two slices of the series could be read", "; ".join(warn[:3]))

    positions = np.array([h.position for h in kept])
    along = positions @ normal
    steps = np.diff(along)
    spacing_k = float(np.median(steps))
    if spacing_k <= 0:
        raise DicomSeriesError(folder, "all slices lie at the same position", "The series cannot form a volume")

    # Gantry tilt: in-plane drift of the positions while advancing along the normal.
    drift = positions - positions[0] - np.outer(along - along[0], normal)
    stack_length = along[-1] - along[0]
    tilt_deg = math.degrees(math.atan2(float(np.linalg.norm(drift[-1])), float(stack_length)))
    array = np.stack(slices).astype(np.float64 if any(s.dtype.kind == "f" for s in slices) else slices[0].dtype)
    spacing_i, spacing_j = kept[0].pixel_spacing[1], kept[0].pixel_spacing[0]
    if tilt_deg > TILT_TOLERANCE_DEG:
        from scipy import ndimage

        fill = float(array.min())
        corrected = np.empty(array.shape, dtype=np.float64)
        for k in range(len(kept)):
            shift_j = float(drift[k] @ col_cos) / spacing_j
            shift_i = float(drift[k] @ row_cos) / spacing_i
            # The slice's content sits at +drift from where an untilted stack would put it; move it back.
            corrected[k] = ndimage.shift(array[k].astype(np.float64), (shift_j, shift_i), order=1, mode="constant", cval=fill)
        array = corrected
        warn.append(
            f"gantry tilt of {tilt_deg:.2f} degrees detected; each slice was shifted in-plane (linear interpolation) "
            "to remove the shear"
        )

    irregular_steps = np.abs(steps - spacing_k) > SPACING_TOLERANCE * spacing_k
    if np.any(irregular_steps):
        gaps = [
            f"{along[i]:.2f} to {along[i + 1]:.2f} mm ({steps[i]:.2f} mm, {kept[i].path.name} -> {kept[i + 1].path.name})"
            for i in np.nonzero(irregular_steps)[0][:4]
        ]
        missing = int(round(float(np.sum(np.maximum(np.round(steps / spacing_k) - 1, 0)))))
        description = (
            f"{missing} slice(s) missing" if missing and np.allclose(steps / spacing_k, np.round(steps / spacing_k), atol=0.05)
            else "irregular slice spacing"
        )
        if irregular == "error":
            raise DicomSeriesError(
                folder,
                f"{description}: spacing is {spacing_k:.3f} mm but gaps differ at {'; '.join(gaps)}",
                "Re-export the complete series, or load with resampling to fill the gaps by interpolation",
            )
        count = int(round(stack_length / spacing_k)) + 1
        targets = along[0] + np.arange(count) * spacing_k
        upper = np.clip(np.searchsorted(along, targets, side="right"), 1, len(along) - 1)
        lower = upper - 1
        weight = np.clip((targets - along[lower]) / (along[upper] - along[lower]), 0.0, 1.0)[:, None, None]
        array = array[lower] * (1 - weight) + array[upper] * weight
        warn.append(
            f"{description} at {'; '.join(gaps)}; resampled to {count} slices at {spacing_k:.3f} mm by linear "
            "interpolation along the stack"
        )

    direction = np.column_stack([row_cos, col_cos, normal])
    origin = positions[0]
    if progress is not None:
        progress(1.0)
    metadata = {
        "source_format": "DICOM series",
        "source_path": str(folder),
        "series_uid": chosen.series_uid,
        "series_description": chosen.description,
        "files_used": len(kept),
        "other_series": others,
        "warnings": warn,
        "gantry_tilt_deg": round(tilt_deg, 4),
    }
    return Volume(
        _store(array),
        spacing=(spacing_i, spacing_j, spacing_k),
        origin=tuple(origin),
        direction=direction,
        modality=modality,
        units=units,
        metadata=metadata,
    )


# ----------------------------------------------------------------------------------------------------------------
# Multi-frame files
# ----------------------------------------------------------------------------------------------------------------
def _sequence_item(dataset, *names):
    """Follow nested single-item sequences: ``_sequence_item(ds, 'SharedFunctionalGroupsSequence', ...)``."""
    item = dataset
    for name in names:
        sequence = item.get(name) if item is not None else None
        if not sequence:
            return None
        item = sequence[0]
    return item


def read_multiframe(path):
    """Read a single multi-frame DICOM file (enhanced CT/MR, or legacy multi-frame such as RT dose) as a volume."""
    from ..volume import Volume

    path = Path(path)
    pixels, dataset = decode_pixels(path)
    frames = int(dataset.get("NumberOfFrames", 1) or 1)
    if pixels.ndim != 3 or pixels.shape[0] != frames:
        raise CorruptFileError(
            path, f"expected {frames} grey-level frames, got a pixel array of shape {pixels.shape}",
            "Colour or single-frame images cannot be read as a volume",
        )
    warn: list[str] = []
    shared = dataset.get("SharedFunctionalGroupsSequence")
    per_frame = dataset.get("PerFrameFunctionalGroupsSequence")

    def group_value(frame_index: int, sequence: str, attribute: str):
        if per_frame and frame_index < len(per_frame):
            item = _sequence_item(per_frame[frame_index], sequence)
            if item is not None and attribute in item:
                return item.get(attribute)
        if shared:
            item = _sequence_item(shared[0], sequence)
            if item is not None and attribute in item:
                return item.get(attribute)
        return None

    orientation = _float_list(group_value(0, "PlaneOrientationSequence", "ImageOrientationPatient"), 6)
    if orientation is None:
        orientation = _float_list(dataset.get("ImageOrientationPatient"), 6)
    pixel_spacing = _float_list(group_value(0, "PixelMeasuresSequence", "PixelSpacing"), 2)
    if pixel_spacing is None:
        pixel_spacing = _float_list(dataset.get("PixelSpacing"), 2)
    if orientation is None or pixel_spacing is None:
        raise DicomSeriesError(
            path, "the multi-frame image lacks orientation or pixel spacing", "It cannot be placed in patient space"
        )
    row_cos, col_cos = orientation[:3] / np.linalg.norm(orientation[:3]), orientation[3:] / np.linalg.norm(orientation[3:])
    normal = np.cross(row_cos, col_cos)
    normal /= np.linalg.norm(normal)

    positions = [_float_list(group_value(f, "PlanePositionSequence", "ImagePositionPatient"), 3) for f in range(frames)]
    if all(p is not None for p in positions):
        positions = np.array(positions)
    else:
        first = _float_list(dataset.get("ImagePositionPatient"), 3)
        offsets = dataset.get("GridFrameOffsetVector")
        if first is None:
            raise DicomSeriesError(path, "the multi-frame image has no frame positions", "It cannot be placed in space")
        if offsets is not None and len(offsets) == frames:
            positions = first + np.outer(np.asarray([float(o) for o in offsets]), normal)
        else:
            step = float(dataset.get("SpacingBetweenSlices", 0) or dataset.get("SliceThickness", 0) or 0)
            if step <= 0:
                raise DicomSeriesError(path, "no frame positions, offsets or slice spacing", "It cannot be stacked")
            positions = first + np.outer(np.arange(frames) * step, normal)
            warn.append(f"{path.name}: frame positions taken from SpacingBetweenSlices/SliceThickness ({step} mm)")

    values = np.empty(pixels.shape, dtype=np.float64)
    for f in range(frames):
        slope = group_value(f, "PixelValueTransformationSequence", "RescaleSlope")
        intercept = group_value(f, "PixelValueTransformationSequence", "RescaleIntercept")
        if slope is None and intercept is None:
            slope, intercept = _rescale(dataset)
        slope, intercept = float(slope if slope is not None else 1.0), float(intercept if intercept is not None else 0.0)
        scaling = float(dataset.get("DoseGridScaling", 1.0) or 1.0) if dataset.get("Modality") == "RTDOSE" else 1.0
        values[f] = pixels[f].astype(np.float64) * slope * scaling + intercept

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
    modality = str(dataset.get("Modality", "") or "")
    units = "Gy" if modality == "RTDOSE" else _units(dataset, modality)
    metadata = {
        "source_format": "DICOM multi-frame",
        "source_path": str(path),
        "series_uid": str(dataset.get("SeriesInstanceUID", "")),
        "series_description": str(dataset.get("SeriesDescription", "") or ""),
        "files_used": 1,
        "other_series": [],
        "warnings": warn,
    }
    return Volume(
        _store(values) if modality != "RTDOSE" else values.astype(np.float32),
        spacing=(float(pixel_spacing[1]), float(pixel_spacing[0]), spacing_k),
        origin=tuple(positions[0]),
        direction=np.column_stack([row_cos, col_cos, normal]),
        modality=modality,
        units=units,
        metadata=metadata,
    )


def is_dicom_file(path) -> bool:
    """True if the file starts with the DICOM preamble and magic ``DICM``."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(132)
    except OSError:
        return False
    return len(head) == 132 and head[128:132] == b"DICM"


def list_series(folder) -> list[dict[str, Any]]:
    """Summaries of the image series in a folder (largest first), for a series chooser."""
    return [s.summary() for s in scan_folder(folder).series]


# ----------------------------------------------------------------------------------------------------------------
# Writing (tests, demos and export of synthetic volumes)
# ----------------------------------------------------------------------------------------------------------------
def write_dicom_series(
    volume,
    folder,
    *,
    series_uid: str | None = None,
    study_uid: str | None = None,
    rescale_intercept: float | None = None,
    rescale_slope: float = 1.0,
    description: str = "Voxelscope export",
    file_names: Sequence[str] | None = None,
    series_number: int = 1,
) -> list[Path]:
    """Write ``volume`` as a single-frame CT/MR image series (one file per k slice), uncompressed.

    Values are stored as ``(value - intercept) / slope`` in unsigned 16 bits when ``rescale_intercept`` is given
    (e.g. ``-1024`` for CT, like most scanners), else as signed 16 bits with intercept 0. Returns the file paths.
    """
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    modality = volume.modality or "OT"
    sop_class = {"CT": "1.2.840.10008.5.1.4.1.1.2", "MR": "1.2.840.10008.5.1.4.1.1.4"}.get(
        modality, "1.2.840.10008.5.1.4.1.1.7"
    )
    series_uid = series_uid or generate_uid()
    study_uid = study_uid or generate_uid()
    frame_uid = generate_uid()
    values = np.asarray(volume.array, dtype=np.float64)
    if rescale_intercept is not None:
        stored = np.rint((values - rescale_intercept) / rescale_slope)
        if stored.min() < 0 or stored.max() > 65535:
            raise ValueError("values do not fit unsigned 16 bits with this rescale")
        stored, signed = stored.astype(np.uint16), False
    else:
        stored = np.rint(values / rescale_slope)
        if stored.min() < -32768 or stored.max() > 32767:
            raise ValueError("values do not fit signed 16 bits")
        stored, signed = stored.astype(np.int16), True
    direction = volume.direction
    nx, ny, nz = volume.dimensions
    paths = []
    for k in range(nz):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = sop_class
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        name = file_names[k] if file_names is not None else f"slice_{k:04d}.dcm"
        path = folder / name
        ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
        ds.SOPClassUID = sop_class
        ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
        ds.StudyInstanceUID = study_uid
        ds.SeriesInstanceUID = series_uid
        ds.FrameOfReferenceUID = frame_uid
        ds.Modality = modality
        ds.SeriesDescription = description
        ds.SeriesNumber = series_number
        ds.InstanceNumber = k + 1
        ds.PatientName = "Phantom^Voxelscope"
        ds.PatientID = "VOXELSCOPE-0001"
        ds.ImageType = ["ORIGINAL", "PRIMARY", "AXIAL"]
        position = volume.index_to_world((0, 0, k))
        ds.ImagePositionPatient = [f"{v:.6f}".rstrip("0").rstrip(".") for v in position]
        ds.ImageOrientationPatient = [f"{v:.6f}" for v in np.concatenate([direction[:, 0], direction[:, 1]])]
        ds.PixelSpacing = [f"{volume.spacing[1]:.6f}", f"{volume.spacing[0]:.6f}"]
        ds.SliceThickness = f"{volume.spacing[2]:.6f}"
        ds.Rows, ds.Columns = ny, nx
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.BitsAllocated = 16
        ds.BitsStored = 16
        ds.HighBit = 15
        ds.PixelRepresentation = 1 if signed else 0
        ds.RescaleIntercept = f"{rescale_intercept if rescale_intercept is not None else 0:g}"
        ds.RescaleSlope = f"{rescale_slope:g}"
        if modality == "CT":
            ds.RescaleType = "HU"
        ds.PixelData = np.ascontiguousarray(stored[k]).tobytes()
        ds.save_as(path, enforce_file_format=True)
        paths.append(path)
    return paths
