"""Scanning a DICOM folder: headers without pixels, one entry per 2D frame, grouping into stacks, choosing one.

- Headers are read with ``stop_before_pixels`` (fast on large series, :mod:`.headers`); pixels only for the chosen
  stack.
- Every file is read inside its own ``try``: a file that is not DICOM, is truncated, or has a malformed element
  (``NumberOfFrames '1A'``, a multi-valued ``Rows``, ``RescaleSlope 'x'`` or ``0``) is skipped with a warning
  naming the file and the element, and never blocks the rest of the folder. FIFOs and devices are skipped unread.
- pydicom's own warnings (invalid values for a VR, ...) are captured into the scan's warnings, not printed.
- A multi-frame *enhanced* file contributes one entry per frame (geometry from its functional groups), and a
  Siemens MOSAIC file one entry per tile (:mod:`.mosaic`), so both stack like single-frame slices.
- Entries are grouped by SeriesInstanceUID, then by image geometry (size and orientation), so a localizer (scout)
  saved in the same series or folder never ends up in the stack. The largest stack is chosen unless the caller
  names a series; the others are listed with the reason they were not used.
"""

from __future__ import annotations

import os
import stat
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..errors import DicomSeriesError
from ..safety import one_line
from .headers import ElementError, SliceHeader, number, pydicom_module, read_header, rescale, text, vector
from .mosaic import mosaic_tiles
from .multiframe import enhanced_frames, is_enhanced
from .stack import count_volumes


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
            "files": len(set(self.files)),
            "rows": self.rows,
            "columns": self.columns,
        }


@dataclass
class FolderScan:
    """The result of scanning a folder: image series candidates, files skipped with reasons, pydicom warnings."""

    folder: Path
    series: list[SeriesInfo]
    skipped: list[tuple[Path, str]]
    notes: list[str] = field(default_factory=list)

    def warnings(self) -> list[str]:
        return [f"{path}: skipped, {reason}" for path, reason in self.skipped] + list(self.notes)


# ----------------------------------------------------------------------------------------------------------------
# Elements, read defensively
# ----------------------------------------------------------------------------------------------------------------
def slice_headers(path: Path, dataset) -> list[SliceHeader]:
    """The 2D images of one file: itself, its enhanced frames, or its MOSAIC tiles."""
    spacing = vector(dataset, "PixelSpacing", 2)
    slope, intercept = rescale(dataset)
    text(dataset, "RescaleType")  # read later for the units: a damaged value is named now
    instance = number(dataset, "InstanceNumber", None, kind=int)
    header = SliceHeader(
        path=path,
        series_uid=text(dataset, "SeriesInstanceUID") or "unknown-series",
        sop_uid=text(dataset, "SOPInstanceUID") or path.name,
        rows=number(dataset, "Rows", 0, kind=int),
        columns=number(dataset, "Columns", 0, kind=int),
        position=vector(dataset, "ImagePositionPatient", 3),
        orientation=vector(dataset, "ImageOrientationPatient", 6),
        pixel_spacing=None if spacing is None else (float(spacing[0]), float(spacing[1])),
        frames=number(dataset, "NumberOfFrames", 1, kind=int) or 1,
        modality=text(dataset, "Modality"),
        description=text(dataset, "SeriesDescription"),
        image_type=text(dataset, "ImageType"),
        echo=text(dataset, "EchoNumbers") or None,
        temporal=text(dataset, "TemporalPositionIdentifier") or None,
        instance=instance,
        acquisition=text(dataset, "AcquisitionNumber") or None,
        slope=slope,
        intercept=intercept,
    )
    if header.rows < 0 or header.columns < 0 or header.frames < 1:
        raise ElementError(f"Rows {header.rows}, Columns {header.columns} or NumberOfFrames {header.frames} is invalid")
    if header.rows == 0 or header.columns == 0:
        return [header]
    if is_enhanced(dataset):
        return enhanced_frames(header, dataset)
    tiles = mosaic_tiles(header, dataset)
    return tiles if tiles is not None else [header]


def _iter_files(folder: Path) -> tuple[list[Path], list[tuple[Path, str]]]:
    files, special = [], []
    for root, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(names):
            if name.startswith(".") or name.upper() == "DICOMDIR":
                continue
            path = Path(root) / name
            try:
                mode = os.stat(path).st_mode
            except OSError as exc:
                special.append((path, f"cannot be read ({exc.strerror})"))
                continue
            if not stat.S_ISREG(mode):
                special.append((path, "not a regular file (a FIFO, device or socket)"))
                continue
            files.append(path)
    return files, special


def _summarise_notes(notes: list[tuple[Path, str]]) -> list[str]:
    """pydicom's warnings, one line per distinct message with how many files gave it."""
    counts = Counter(message for _, message in notes)
    first = {}
    for path, message in notes:
        first.setdefault(message, path)
    lines = []
    for message, count in counts.items():
        where = f"{first[message]}" + (f" and {count - 1} more files" if count > 1 else "")
        lines.append(f"{where}: pydicom: {message[:200]}")
    return lines


def scan_files(folder: Path, files: list[Path], progress: Callable[[float], None] | None = None,
               skipped: list[tuple[Path, str]] | None = None) -> FolderScan:
    """Read the headers of ``files`` and group their images into stack candidates."""
    pydicom = pydicom_module()
    groups: dict[tuple, SeriesInfo] = {}
    skipped = list(skipped or [])
    notes: list[tuple[Path, str]] = []
    for index, path in enumerate(files):
        if progress is not None and index % 32 == 0:
            progress(index / max(len(files), 1))
        file_notes: list[str] = []
        try:
            dataset = read_header(path, file_notes)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    headers = slice_headers(path, dataset)
                finally:
                    file_notes.extend(one_line(w.message) for w in caught)
        except pydicom.errors.InvalidDicomError:
            skipped.append((path, "not a DICOM file"))
            continue
        except ElementError as exc:
            skipped.append((path, f"{exc}"))
            continue
        except MemoryError:
            skipped.append((path, "the header declares more data than fits in memory"))
            continue
        except Exception as exc:  # pydicom raises many types for damaged headers
            skipped.append((path, f"unreadable or truncated DICOM header ({type(exc).__name__}: {one_line(exc)[:160]})"))
            continue
        finally:
            notes.extend((path, message) for message in file_notes)
        if headers[0].rows <= 0 or headers[0].columns <= 0:
            skipped.append((path, f"no image in this object (Modality {headers[0].modality or 'unknown'})"))
            continue
        for header in headers:
            key = header.geometry_key
            if key not in groups:
                groups[key] = SeriesInfo(header.series_uid, header.description, header.modality, header.rows,
                                         header.columns)
            groups[key].headers.append(header)
            groups[key].files.append(path)
    series = sorted(groups.values(), key=lambda s: (-s.size, s.series_uid))
    if progress is not None:
        progress(1.0)
    return FolderScan(folder, series, skipped, _summarise_notes(notes))


def scan_folder(folder, progress: Callable[[float], None] | None = None) -> FolderScan:
    """Read every file's header in ``folder`` (recursively) and group the images into stack candidates."""
    folder = Path(folder)
    files, special = _iter_files(folder)
    if not files and not special:
        raise DicomSeriesError(folder, "the folder contains no files", "Choose the folder that holds the DICOM series")
    return scan_files(folder, files, progress, special)


def choose_series(scan: FolderScan, series_uid: str | None) -> tuple[SeriesInfo, list[dict[str, Any]]]:
    """The stack to load (the largest, or the one asked for) and a summary of the others with the reason."""
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


def is_dicom_file(path) -> bool:
    """True if the file starts with the DICOM preamble and magic ``DICM``."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return False
        with open(path, "rb") as handle:
            head = handle.read(132)
    except OSError:
        return False
    return len(head) == 132 and head[128:132] == b"DICM"


def list_series(folder) -> list[dict[str, Any]]:
    """Summaries of the image series in a folder (largest first), for a series chooser.

    Each summary has ``series_uid``, ``description``, ``modality``, ``slices`` (2D images), ``files``, ``rows``,
    ``columns`` and ``volumes`` (how many volumes the stack holds: time points, echoes, MOSAIC files).
    """
    return [{**s.summary(), "volumes": count_volumes(s.headers)} for s in scan_folder(folder).series]
