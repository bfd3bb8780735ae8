"""Reading DICOM images into a volume: scan, choose a series and a volume, read the slices, place them."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from ...volume import Volume
from ..errors import DicomSeriesError
from .headers import read_header, study_fields
from .multiframe import read_multiframe
from .pixels import store
from .scan import FolderScan, SeriesInfo, choose_series, scan_files, scan_folder
from .stack import (
    SliceFrame,
    choose_volume,
    correct_tilt,
    read_slices,
    regularise_spacing,
    remove_duplicates,
    require_geometry,
)


def read_dicom_series(
    folder,
    *,
    series_uid: str | None = None,
    irregular: str = "resample",
    allow_gaps: bool = False,
    volume_index: int | None = None,
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
    allow_gaps : bool
        Interpolate across gaps of more than :data:`.stack.MAX_INTERPOLATED_SLICES` missing slices.
    volume_index : int, optional
        Which volume of a series holding several (echoes, time points, MOSAIC files); default the first.
    progress : callable, optional
        Called with a fraction in [0, 1].
    """
    folder = Path(folder)
    scan = scan_folder(folder, progress=None if progress is None else (lambda f: progress(0.3 * f)))
    return _read(scan, folder, series_uid, irregular, allow_gaps, volume_index, progress)


def read_dicom_file(path, *, series_uid=None, irregular="resample", allow_gaps=False, volume_index=None,
                    progress=None):
    """A single DICOM file: a multi-frame volume (enhanced or legacy, MOSAIC), or one slice of its folder's series."""
    path = Path(path)
    single = scan_files(path.parent, [path])
    if single.series and single.series[0].size > 1:  # enhanced frames or MOSAIC tiles: the file is a volume
        return _read(single, path, series_uid, irregular, allow_gaps, volume_index, progress)
    if single.series and single.series[0].headers[0].frames > 1:
        return read_multiframe(path)
    if not single.series:
        reason = single.skipped[0][1] if single.skipped else "no image in this file"
        raise DicomSeriesError(path, reason, "Choose a DICOM image file or a folder holding a series")
    uid = series_uid or single.series[0].series_uid
    return read_dicom_series(path.parent, series_uid=uid, irregular=irregular, allow_gaps=allow_gaps,
                             volume_index=volume_index, progress=progress)


def _read(scan: FolderScan, folder: Path, series_uid, irregular, allow_gaps, volume_index, progress):
    if irregular not in ("resample", "error"):
        raise ValueError(f"irregular must be 'resample' or 'error', got {irregular!r}")
    warn = scan.warnings()
    chosen, others = choose_series(scan, series_uid)
    for group in scan.series:  # images of the chosen series left out for their size or orientation: say which
        if group is not chosen and group.series_uid == chosen.series_uid:
            files = sorted({p.name for p in group.files})
            warn.append(f"{group.files[0]}{f' and {len(files) - 1} more files' if len(files) > 1 else ''}: not used, "
                        f"same series but {group.columns}x{group.rows} images or another orientation "
                        "(a localizer, or a damaged header)")
    if len(chosen.headers) == 1 and chosen.headers[0].frames > 1 and chosen.headers[0].frame is None:
        volume = read_multiframe(chosen.headers[0].path)
        volume.metadata["warnings"] = warn + volume.metadata.get("warnings", [])
        volume.metadata["other_series"] = others
        return volume
    metadata: dict = {}
    headers, frame = _one_volume(chosen, folder, volume_index, warn, metadata)
    slices = read_slices(headers, folder, chosen.modality, warn,
                         None if progress is None else (lambda f: progress(0.3 + 0.6 * f)))
    positions = np.array([h.position for h in slices.headers])
    along = positions @ frame.normal
    pixel_spacing = slices.headers[0].pixel_spacing
    array, origin, tilt_deg = correct_tilt(slices.array, positions, frame, pixel_spacing, warn)
    names = [h.name for h in slices.headers]
    array, spacing_k, invented = regularise_spacing(array, along, names, folder, irregular, allow_gaps, warn)
    if progress is not None:
        progress(1.0)
    mosaic = slices.headers[0].mosaic is not None
    metadata.update({
        "source_format": "DICOM MOSAIC" if mosaic else "DICOM series" if slices.headers[0].frame is None
        else "DICOM multi-frame",
        "source_path": str(folder),
        "series_uid": chosen.series_uid,
        "series_description": chosen.description,
        "files_used": len({h.path for h in slices.headers}),
        "other_series": others,
        "warnings": warn,
        "gantry_tilt_deg": round(tilt_deg, 4),
        "interpolated_slices": invented,
        "dicom": study_fields(slices.headers[0].path),
    })
    try:
        return Volume(store(array), spacing=(pixel_spacing[1], pixel_spacing[0], spacing_k), origin=tuple(origin),
                      direction=frame.direction, modality=chosen.modality, units=slices.units, metadata=metadata)
    except ValueError as exc:
        raise DicomSeriesError(folder, f"the slices do not form a valid volume ({exc})") from exc


def _one_volume(chosen: SeriesInfo, folder: Path, volume_index, warn: list[str], metadata: dict):
    """The sorted headers of the volume to load, and the slice frame."""
    require_geometry(chosen.headers)
    try:
        frame = SliceFrame.from_orientation(chosen.headers[0].orientation)
    except ValueError as exc:
        raise DicomSeriesError(chosen.headers[0].path, f"the image orientation is invalid ({exc})") from exc
    headers = remove_duplicates(chosen.headers, warn)
    headers = choose_volume(headers, frame.normal, volume_index, warn, metadata)
    if len(headers) < 2:
        raise DicomSeriesError(
            folder,
            f"the chosen series has a single slice ({headers[0].name}); a volume needs at least two",
            "Check that the whole series was copied",
        )
    if any(h.pixel_spacing[0] <= 0 or h.pixel_spacing[1] <= 0 for h in headers):
        bad = next(h for h in headers if h.pixel_spacing[0] <= 0 or h.pixel_spacing[1] <= 0)
        raise DicomSeriesError(bad.path, f"PixelSpacing {list(bad.pixel_spacing)} is not positive")
    headers.sort(key=lambda h: float(h.position @ frame.normal))
    return headers, frame


__all__ = ["read_dicom_file", "read_dicom_series", "read_header"]
