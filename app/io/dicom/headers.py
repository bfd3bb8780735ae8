"""One DICOM file's header, read without its pixels: the elements Voxelscope checks, and one entry per 2D image.

- :func:`read_header` reads a file with ``stop_before_pixels``, pydicom's own warnings captured into notes.
- :func:`element`, :func:`number`, :func:`vector`, :func:`text` and :func:`rescale` read one element each and turn a
  malformed value (``NumberOfFrames '1A'``, a multi-valued ``Rows``, ``RescaleSlope 'x'`` or ``0``) into an
  :class:`ElementError` that names it.
- :class:`SliceHeader` is one 2D image (a file, an enhanced frame or a MOSAIC tile) as the folder scan
  (:mod:`.scan`) groups it into stacks; :func:`study_fields` the study's identity for the provenance.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..safety import one_line


class ElementError(ValueError):
    """A data element is present but malformed; the message names it."""


def pydicom_module():
    """pydicom, imported on first use (a heavy import the command line does not always need)."""
    import pydicom

    return pydicom


@dataclass
class SliceHeader:
    """One 2D image of the folder: a single-frame file, one frame of an enhanced file, or one MOSAIC tile."""

    path: Path
    series_uid: str
    sop_uid: str
    rows: int
    columns: int
    position: np.ndarray | None
    orientation: np.ndarray | None  # (6,): row cosines then column cosines
    pixel_spacing: tuple[float, float] | None  # (between rows, between columns)
    frames: int  # NumberOfFrames of the file
    modality: str
    description: str
    image_type: str
    echo: Any = None
    temporal: Any = None
    instance: int | None = None
    acquisition: Any = None
    slope: float = 1.0
    intercept: float = 0.0
    frame: int | None = None  # index of the frame (enhanced) or tile (MOSAIC) in the file
    volume_key: Any = None  # set when the file itself says which volume the image belongs to
    mosaic: Any = None  # MosaicLayout of a MOSAIC tile

    @property
    def geometry_key(self) -> tuple:
        orientation = None if self.orientation is None else tuple(np.round(self.orientation, 3))
        return (self.series_uid, self.rows, self.columns, orientation)

    @property
    def name(self) -> str:
        return self.path.name if self.frame is None else f"{self.path.name} frame {self.frame + 1}"


def element(dataset, keyword: str):
    """``dataset.get(keyword)``; pydicom converts values lazily, so a damaged value raises here: name it."""
    try:
        return dataset.get(keyword)
    except Exception as exc:  # pydicom raises many types for damaged values
        raise ElementError(f"the element {keyword} cannot be decoded ({one_line(exc)})") from exc


def number(dataset, keyword: str, default=None, *, kind=float, positive: bool = False):
    """A single number from ``keyword`` (``default`` when absent or empty); malformed values name the element."""
    value = element(dataset, keyword)
    if value is None or value == "":
        return default
    if isinstance(value, (list, tuple)) or type(value).__name__ == "MultiValue":
        raise ElementError(f"{keyword} holds {len(value)} values where one is expected")
    try:
        result = kind(float(value)) if kind is int else kind(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ElementError(f"{keyword} '{value}' is not a number") from exc
    if kind is int and float(value) != int(float(value)):
        raise ElementError(f"{keyword} '{value}' is not a whole number")
    if not np.isfinite(result) or (positive and result <= 0):
        raise ElementError(f"{keyword} '{value}' is not a usable value")
    return result


def float_list(value, count: int) -> np.ndarray | None:
    """``count`` finite floats from a multi-valued element, or None when absent or malformed."""
    if value is None:
        return None
    try:
        array = np.array([float(v) for v in value], dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return array if array.shape == (count,) and np.all(np.isfinite(array)) else None


def vector(dataset, keyword: str, count: int) -> np.ndarray | None:
    """``count`` finite numbers from ``keyword``; None when absent, :class:`ElementError` when malformed."""
    value = element(dataset, keyword)
    if value is None or value == "":
        return None
    result = float_list(value if isinstance(value, (list, tuple)) or type(value).__name__ == "MultiValue"
                        else [value], count)
    if result is None:
        raise ElementError(f"{keyword} must hold {count} finite numbers, got {one_line(value)[:80]}")
    return result


def text(dataset, keyword: str) -> str:
    value = element(dataset, keyword)
    if value is None:
        return ""
    if isinstance(value, (list, tuple)) or type(value).__name__ == "MultiValue":
        return "\\".join(str(v) for v in value)
    return str(value)


def rescale(dataset) -> tuple[float, float]:
    """RescaleSlope and RescaleIntercept (1 and 0 when absent); a zero or non-numeric slope names the element."""
    slope = number(dataset, "RescaleSlope", 1.0)
    intercept = number(dataset, "RescaleIntercept", 0.0)
    if slope == 0:
        raise ElementError("RescaleSlope is 0, which would make every value the same")
    return slope, intercept


def read_header(path: Path, notes: list[str] | None = None):
    """Read a DICOM header without pixels; raises ``InvalidDicomError`` for non-DICOM files.

    pydicom's warnings go to ``notes`` (or are dropped) instead of standard error.
    """
    pydicom = pydicom_module()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            dataset = pydicom.dcmread(path, stop_before_pixels=True)
        except pydicom.errors.InvalidDicomError:
            # Files without the 128-byte preamble ("raw" DICOM from some PACS exports): accept them only if a
            # forced parse finds an SOP class, so random files are not misread as DICOM.
            dataset = pydicom.dcmread(path, stop_before_pixels=True, force=True)
            if "SOPClassUID" not in dataset:
                raise
    if notes is not None:
        notes.extend(one_line(w.message) for w in caught)
    return dataset


#: Patient, study, series and equipment elements kept in ``volume.metadata["dicom"]`` (the provenance panel shows them).
STUDY_KEYWORDS = (
    "PatientName", "PatientID", "PatientBirthDate", "PatientSex", "PatientAge", "StudyDate", "StudyTime",
    "StudyDescription", "StudyInstanceUID", "AccessionNumber", "SeriesNumber", "SeriesDescription", "SeriesDate",
    "Modality", "BodyPartExamined", "ProtocolName", "Manufacturer", "ManufacturerModelName", "InstitutionName",
    "SliceThickness", "KVP", "ConvolutionKernel", "MagneticFieldStrength", "RepetitionTime", "EchoTime",
)


def study_fields(path: Path) -> dict[str, str]:
    """The :data:`STUDY_KEYWORDS` present in the header of ``path`` as text (an unreadable value is left out)."""
    try:
        dataset = read_header(path)
    except Exception:  # the file was read once already; a second failure only loses the listing
        return {}
    fields = {}
    for keyword in STUDY_KEYWORDS:
        try:
            value = text(dataset, keyword)
        except ElementError:
            continue
        if value:
            fields[keyword] = one_line(value)[:200]
    return fields
