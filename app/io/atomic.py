"""Atomic file output: write to a temporary file next to the target, then rename over it.

A crash, a cancelled export or a full disk never leaves a half-written file under the user's chosen name, and an
existing file is only replaced when the caller says so.

- Temporary files are named ``.voxelscope-tmp-<name>-<random><suffix>`` in the target's folder (same file
  system, so the final rename is atomic). Ones left behind by killed runs (older than an hour) are removed the
  next time something is written to that folder.
- The data is flushed to disk (``fsync``) before the rename, so a full disk (``ENOSPC``) shows up as an error
  while the target is still untouched; the temporary file is then removed.
- Every error names the user's path, never the temporary one.
- Formats with companion files (a ``.mhd`` and its ``.zraw``) check all of them for overwriting before anything is
  written (:func:`check_companions`) and commit them together (:func:`atomic_outputs`).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import secrets
import time
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from .errors import FileExistsRefusal, VolumeWriteError

#: Prefix of every temporary file Voxelscope writes; recognisable so stale ones can be cleaned up.
TEMP_PREFIX = ".voxelscope-tmp-"
#: Temporary files older than this (seconds) belong to runs that were killed.
STALE_AFTER = 3600.0


def sidecar_json(data) -> str:
    """``data`` as indented JSON text with a final newline: NumPy scalars and arrays as numbers and lists, paths
    as strings; anything else is a ``TypeError`` (a sidecar never holds a silently stringified object)."""
    def default(value):
        if isinstance(value, Path):
            return str(value)
        return numpy_json(value)

    return json.dumps(data, indent=2, default=default) + "\n"


def numpy_json(value):
    """A NumPy integer, float or array as the int, float or list JSON stores (a ``json.dumps`` ``default``);
    anything else is a ``TypeError``."""
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def remove_stale_temporaries(folder, *, max_age: float = STALE_AFTER) -> list[Path]:
    """Delete ``.voxelscope-tmp-*`` files in ``folder`` older than ``max_age`` seconds; returns what was removed."""
    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        if not entry.name.startswith(TEMP_PREFIX):
            continue
        try:
            if entry.is_file(follow_symlinks=False) and now - entry.stat(follow_symlinks=False).st_mtime > max_age:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue  # another process removed or is using it
    return removed


def _describe(exc: OSError) -> str:
    if exc.errno == errno.ENOSPC:
        return "the disk is full (no space left on device)"
    if exc.errno == errno.EDQUOT:
        return "the disk quota is exceeded"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if exc.errno == errno.EROFS:
        return "the file system is read-only"
    return exc.strerror or type(exc).__name__


def write_error(path: Path, exc: BaseException, temporaries: Sequence[Path] = ()) -> VolumeWriteError:
    """A :class:`VolumeWriteError` for ``exc`` naming ``path`` (temporary names replaced by it)."""
    if isinstance(exc, OSError):
        text = f"{path}: could not be written: {_describe(exc)}"
    else:
        text = str(exc)
        for temporary in temporaries:
            text = text.replace(str(temporary), str(path)).replace(temporary.name, path.name)
        if str(path) not in text:
            text = f"{path}: {text}"
    return VolumeWriteError(" ".join(text.split()))


def check_target(path: Path, *, overwrite: bool) -> Path:
    """Refuse a target that exists (unless ``overwrite``), is a folder, or whose folder is missing or read-only."""
    path = Path(path)
    if path.is_dir():
        raise VolumeWriteError(f"{path} is a folder; give a file name for the output")
    if path.exists() and not overwrite:
        raise FileExistsRefusal(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise VolumeWriteError(f"{path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise VolumeWriteError(f"{path}: the folder {folder} is not writable")
    return folder


def check_companions(path, companions: Sequence, *, overwrite: bool) -> None:
    """Check ``path`` and its companion files (e.g. a ``.zraw``) for overwriting before anything is written."""
    for target in [Path(path), *map(Path, companions)]:
        check_target(target, overwrite=overwrite)


def _temporary_for(path: Path, folder: Path, suffix: str | None) -> Path:
    # Keep compound extensions such as .nii.gz for extension-driven writers.
    if suffix is None:
        suffix = "".join(path.suffixes[-2:]) if path.name.lower().endswith(".gz") else path.suffix
    stem = path.name[: len(path.name) - len(suffix)] if suffix and path.name.endswith(suffix) else path.stem
    for _ in range(100):
        candidate = folder / f"{TEMP_PREFIX}{stem[:80]}-{secrets.token_hex(4)}{suffix}"
        try:
            handle = os.open(candidate, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            continue
        os.close(handle)
        return candidate
    raise VolumeWriteError(f"{path}: could not create a temporary file in {folder}")


def _flush(temporary: Path) -> None:
    handle = os.open(temporary, os.O_RDONLY)
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


@contextlib.contextmanager
def atomic_outputs(paths: Sequence, *, overwrite: bool = False, suffixes: Sequence[str | None] | None = None
                   ) -> Iterator[list[Path]]:
    """Yield temporary paths for several targets; on success rename them all to their targets.

    ``paths[0]`` is the file the user named (errors name it); its companions are renamed first and it last, so a
    reader never finds a header without its data. On any error no target is touched and every temporary file is
    removed; if a later rename fails, the targets already renamed that did not exist before are removed again.
    """
    paths = [Path(p) for p in paths]
    suffixes = list(suffixes) if suffixes is not None else [None] * len(paths)
    folders = [check_target(p, overwrite=overwrite) for p in paths]
    for folder in set(folders):
        remove_stale_temporaries(folder)
    temporaries: list[Path] = []
    try:
        for path, folder, suffix in zip(paths, folders, suffixes):
            temporaries.append(_temporary_for(path, folder, suffix))
        yield list(temporaries)
        for path, temporary in zip(paths, temporaries):
            if not temporary.exists() or temporary.stat().st_size == 0:
                raise VolumeWriteError(f"{path}: the writer produced no data")
            _flush(temporary)
        existed = [p.exists() for p in paths]
        if not overwrite and any(existed):  # created by someone else while we were writing
            raise FileExistsRefusal(paths[existed.index(True)])
        mode = 0o666 & ~_umask()  # temporary files are created 0600; give the file the user's usual mode
        done: list[Path] = []
        try:
            for path, temporary in reversed(list(zip(paths, temporaries))):
                os.chmod(temporary, mode)
                os.replace(temporary, path)
                done.append(path)
        except OSError:
            for path in done:
                if not existed[paths.index(path)]:
                    with contextlib.suppress(OSError):
                        path.unlink()
            raise
    except OSError as exc:  # a full disk, a quota, permissions
        raise write_error(paths[0], exc, temporaries) from exc
    except Exception as exc:
        if any(t.name in str(exc) for t in temporaries):  # a writer's message naming the temporary file
            raise write_error(paths[0], exc, temporaries) from exc
        raise
    finally:
        for temporary in temporaries:
            with contextlib.suppress(OSError):
                temporary.unlink()


@contextlib.contextmanager
def atomic_output(path, *, overwrite: bool = False, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success rename it to ``path``.

    ``suffix`` is the temporary file's extension (default: the target's, so writers that choose a format by
    extension work). On any exception the temporary file is removed and the target is untouched; errors are
    :class:`VolumeWriteError` naming ``path``.
    """
    with atomic_outputs([path], overwrite=overwrite, suffixes=[suffix]) as temporaries:
        yield temporaries[0]
