"""Running a VTK writer so that every failure is an exception.

A VTK writer reports trouble through its error code and ``ErrorEvent`` (a full disk, a folder that vanished, data
it cannot encode) and otherwise returns normally; a caller that only looks at ``Write()``'s return value can leave a
truncated file behind without a word. :func:`write_with_vtk` is the one place every VTK file output goes through:
it watches both and turns any of them into an ``OSError``. Callers write to the temporary path of
:func:`app.io.atomic.atomic_output`, which names the user's file in the error and never replaces anything with a
failed write.

XML writers (``.vti``, ``.vtp``, ``.vtu``) write zlib-compressed, raw appended data: smaller than base64 and read
by every VTK-based program.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from vtkmodules.util.misc import calldata_type
from vtkmodules.vtkCommonCore import VTK_STRING, vtkCommand
from vtkmodules.vtkCommonMisc import vtkErrorCode


def write_with_vtk(writer_class, data, path) -> None:
    """Write ``data`` (a VTK data object) to ``path`` with a new ``writer_class()``.

    Parameters
    ----------
    writer_class : type
        A VTK writer class, e.g. ``vtkXMLPolyDataWriter`` or ``vtkPNGWriter``.
    data : vtkDataObject
    path : path-like
        Where to write: the temporary file of :func:`app.io.atomic.atomic_output`.

    Raises
    ------
    OSError
        ``ENOSPC`` when the disk is full (VTK says so, or says something failed while the file system has no space
        left: libpng, for one, reports only "Write Error"), ``EIO`` with what VTK said for any other error.
    """
    writer = writer_class()
    if hasattr(writer, "SetCompressorTypeToZLib"):
        writer.SetCompressorTypeToZLib()
        writer.SetDataModeToAppended()
        writer.EncodeAppendedDataOff()
    writer.SetInputData(data)
    writer.SetFileName(str(path))
    messages: list[str] = []

    @calldata_type(VTK_STRING)
    def collect(caller, event, text):
        messages.append(text)

    for source in (writer, writer.GetExecutive()):
        source.AddObserver(vtkCommand.ErrorEvent, collect)
    written = writer.Write()
    code = writer.GetErrorCode()
    del writer  # closes the file now, not when the traceback of an error below is dropped
    if written in (None, 1) and code == 0 and not messages:  # image writers' Write() returns nothing
        return
    if code in (vtkErrorCode.OutOfDiskSpaceError, errno.ENOSPC) or _no_space_left(Path(path).parent):
        raise OSError(errno.ENOSPC, "No space left on device")
    raise OSError(errno.EIO, _reason(code, messages))


def _no_space_left(folder: Path) -> bool:
    try:
        return os.statvfs(folder).f_bavail == 0
    except OSError:
        return False


def _reason(code: int, messages: list[str]) -> str:
    """The most specific thing VTK said: its error code, else the text of its first error message (without the
    source line and the object's address)."""
    if code and code != vtkErrorCode.UnknownError:
        return vtkErrorCode.GetStringFromErrorCode(code)
    for message in messages:
        lines = [line.strip() for line in message.splitlines() if line.strip() and not line.startswith("ERROR: In ")]
        if lines:
            return lines[0].split("): ", 1)[-1]
    return "VTK reported an error"
