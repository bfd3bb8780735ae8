"""Decoding a DICOM file's pixels, rescaling them to physical values, and choosing the stored type.

Compressed transfer syntaxes are decoded by pydicom's plugins (pylibjpeg, pillow); when none can, a
:class:`MissingDecoderError` names the syntax and the package to install. RescaleSlope/RescaleIntercept are applied
per slice (CT in Hounsfield units); the values are checked when the header is scanned (:func:`.scan.rescale`).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import CorruptFileError, MissingDecoderError
from ..safety import one_line, require_fits
from .headers import ElementError, number

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
_UNCOMPRESSED = ("1.2.840.10008.1.2", "1.2.840.10008.1.2.1", "1.2.840.10008.1.2.2", "1.2.840.10008.1.2.1.99")


def _transfer_syntax(dataset) -> tuple[str, str]:
    meta = getattr(dataset, "file_meta", None)
    uid = meta.get("TransferSyntaxUID") if meta is not None else None
    if uid is None:
        return "", "unknown transfer syntax"
    return str(uid), getattr(uid, "name", str(uid))


def decode_pixels(path: Path, dataset=None, notes: list[str] | None = None) -> tuple[np.ndarray, Any]:
    """Read a file fully and return its pixel array and dataset.

    Raises :class:`CorruptFileError` for truncated or damaged pixel data and :class:`MissingDecoderError` when
    the transfer syntax cannot be decoded with the installed plugins. pydicom's warnings go to ``notes``.
    """
    import pydicom

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            return _decode(pydicom, path, dataset)
        finally:
            if notes is not None:
                notes.extend(one_line(w.message) for w in caught)


def _decode(pydicom, path: Path, dataset) -> tuple[np.ndarray, Any]:
    try:
        if dataset is None or "PixelData" not in dataset:
            dataset = pydicom.dcmread(path, force=True)
    except MemoryError as exc:
        raise CorruptFileError(path, "the file declares more data than fits in memory") from exc
    except Exception as exc:  # pydicom raises many types for damaged files
        raise CorruptFileError(path, f"the file is unreadable or truncated ({one_line(exc)[:160]})",
                               "Re-export or re-copy it") from exc
    if "PixelData" not in dataset:
        raise CorruptFileError(path, "the file has no pixel data (it may be truncated)", "Re-export or re-copy it")
    uid, name = _transfer_syntax(dataset)
    _require_pixel_memory(path, dataset)
    try:
        pixels = dataset.pixel_array
    except (NotImplementedError, RuntimeError) as exc:
        text = str(exc)
        compressed = bool(uid) and uid not in _UNCOMPRESSED
        if compressed and ("plugin" in text or "decod" in text.lower() or "handler" in text):
            package = _DECODER_HINTS.get(uid)
            hint = (f"Install {package} into Voxelscope's environment, or convert the series to uncompressed DICOM"
                    if package else "No decoder for this syntax is available to pydicom; convert the series to "
                                    "uncompressed DICOM (for example on the PACS) and open it again")
            raise MissingDecoderError(
                path,
                f"the pixel data is compressed as '{name}' ({uid}) and no installed decoder could read it "
                f"({text.splitlines()[0] if text else type(exc).__name__})",
                hint,
            ) from exc
        raise CorruptFileError(path, f"the pixel data could not be decoded ({one_line(text)[:160]})") from exc
    except MemoryError as exc:
        raise CorruptFileError(path, "the pixel data declares more than fits in memory") from exc
    except Exception as exc:  # ValueError, AttributeError, KeyError, TypeError, struct.error, plugin errors...
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CorruptFileError(
            path, f"the pixel data is damaged or truncated ({first[:160]})", "Re-export or re-copy the file"
        ) from exc
    return np.asarray(pixels), dataset


def _require_pixel_memory(path: Path, dataset) -> None:
    """Refuse declared image sizes that would not fit in memory before a decoder allocates them."""
    try:
        size = (number(dataset, "Rows", 0, kind=int) * number(dataset, "Columns", 0, kind=int)
                * (number(dataset, "NumberOfFrames", 1, kind=int) or 1) * (number(dataset, "SamplesPerPixel", 1, kind=int) or 1)
                * max(number(dataset, "BitsAllocated", 16, kind=int) or 16, 8) // 8)
    except ElementError as exc:
        raise CorruptFileError(path, str(exc)) from exc
    require_fits(path, size, "the pixel data")


def units(dataset, modality: str) -> str:
    """Units of the rescaled values: RescaleType when given (HU, ...), HU for CT, none otherwise."""
    try:
        rescale_type = str(dataset.get("RescaleType", "") or "").upper()
    except Exception:  # a damaged element (unknown VR...): the scan names it; here the units stay unknown
        rescale_type = ""
    if rescale_type == "HU" or (modality == "CT" and rescale_type in ("", "US")):
        return "HU"
    if rescale_type and rescale_type != "US":  # US = unspecified
        return rescale_type
    return ""


def store(values: np.ndarray) -> np.ndarray:
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
