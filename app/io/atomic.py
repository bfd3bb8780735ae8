"""Atomic file output: write to a temporary file next to the target, then rename over it.

A crash or a cancelled export never leaves a half-written file under the user's chosen name, and an existing
file is only replaced when the caller says so.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from .errors import FileExistsRefusal, VolumeWriteError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_output(path, *, overwrite: bool = False, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success rename it to ``path``.

    ``suffix`` is the temporary file's extension (default: the target's, so writers that choose a format by
    extension work). On any exception the temporary file is removed and the target is untouched.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsRefusal(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise VolumeWriteError(f"{path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise VolumeWriteError(f"{path}: the folder {folder} is not writable")
    # Keep compound extensions such as .nii.gz for extension-driven writers.
    suffix = suffix if suffix is not None else "".join(path.suffixes[-2:]) if path.name.endswith(".gz") else path.suffix
    handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=suffix, dir=folder)
    os.close(handle)
    temporary = Path(temporary)
    try:
        yield temporary
        if not temporary.exists() or temporary.stat().st_size == 0:
            raise VolumeWriteError(f"{path}: the writer produced no data")
        if path.exists() and not overwrite:  # created by someone else while we were writing
            raise FileExistsRefusal(path)
        os.chmod(temporary, 0o666 & ~_umask())  # mkstemp creates 0600; give the file the user's usual mode
        os.replace(temporary, path)
    finally:
        if temporary.exists():
            temporary.unlink()
