"""Exceptions raised by the volume readers and writers.

Every message names the file or folder, says what is wrong, and says what the user can do. The command line and
the workbench show ``str(error)`` as it is, without a traceback.
"""

from __future__ import annotations

import re
from pathlib import Path


def _one_line(text) -> str:
    return re.sub(r"\s+", " ", str(text)).strip().rstrip(".") if text else ""


class VolumeReadError(Exception):
    """A volume could not be read. ``path`` is the file or folder at fault, ``hint`` what the user can do.

    The message is always one line (problem and hint are collapsed), so a caller can print it as it is.
    """

    def __init__(self, path, problem: str, hint: str = "") -> None:
        self.path = Path(path) if path is not None else None
        self.problem = _one_line(problem)
        self.hint = _one_line(hint)
        problem, hint = self.problem, self.hint
        text = f"{self.path}: {problem}" if self.path is not None else problem
        if hint:
            text = f"{text}. {hint}"
        super().__init__(text)


class UnsupportedFormatError(VolumeReadError):
    """The path is not a volume format Voxelscope reads."""


class CorruptFileError(VolumeReadError):
    """The file claims a format but its content is damaged or truncated."""


class DicomSeriesError(VolumeReadError):
    """A DICOM folder holds no usable image series, or the chosen series cannot be stacked into a volume."""


class MissingDecoderError(VolumeReadError):
    """The pixel data is compressed with a transfer syntax no installed decoder handles."""


class MeshReadError(VolumeReadError):
    """A surface mesh file (STL, OBJ, PLY, VTP, OFF, optionally gzipped) is damaged or not what it claims."""


class VolumeWriteError(Exception):
    """A volume or mesh could not be written (the message names the file and the reason)."""


class FileExistsRefusal(VolumeWriteError):
    """The output exists and overwriting was not allowed."""

    def __init__(self, path) -> None:
        self.path = Path(path)
        super().__init__(f"{self.path} already exists; choose another name or allow overwriting (--force)")
