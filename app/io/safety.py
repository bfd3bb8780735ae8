"""Checks every reader makes before it trusts a file: what kind of file it is, whether a declared size fits in
memory, and how much a compressed stream may inflate.

A header is a claim, not a fact. Readers here check it against what is on disk *before* allocating: the file is a
regular file (a FIFO blocks forever, ``/dev/zero`` never ends), the declared voxel count fits in the memory this
process may use (the size is quoted in GiB when it does not), and a compressed payload is inflated in chunks with a
cap, so a small file that claims or hides gigabytes is refused instead of exhausting memory. A damaged compressed
stream (CRC error, truncated, trailing garbage) is an error, never data.
"""

from __future__ import annotations

import bz2
import os
import re
import stat
import zlib
from pathlib import Path

from .errors import CorruptFileError, VolumeReadError

#: Read this much at a time when streaming a file or a decompressor.
CHUNK = 1 << 20
#: Readers need the declared array plus working copies (conversion, transposition): refuse sizes whose
#: ``COPIES`` multiple would not fit in the memory available.
COPIES = 2
#: Set by tests (or a caller) to pretend the machine has this many bytes available; None = measure.
memory_override: int | None = None


def one_line(text) -> str:
    """``text`` on one line (newlines and runs of spaces collapsed), for messages shown as they are."""
    return re.sub(r"\s+", " ", str(text)).strip()


def gib(nbytes: float) -> str:
    """A byte count in GiB with three significant digits ("2.5 GiB", "0.00391 GiB")."""
    return f"{nbytes / 2**30:.3g} GiB"


def require_regular_file(path: Path, what: str = "the file") -> os.stat_result:
    """Refuse anything that is not a regular file (FIFOs, devices, sockets, folders) before opening it."""
    try:
        info = os.stat(path)
    except FileNotFoundError as exc:
        raise VolumeReadError(path, f"{what} does not exist", "Check the path") from exc
    except OSError as exc:
        raise VolumeReadError(path, f"{what} cannot be read ({exc.strerror})") from exc
    if stat.S_ISDIR(info.st_mode):
        raise VolumeReadError(path, f"{what} is a folder, not a file")
    if not stat.S_ISREG(info.st_mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(info.st_mode) else "a device" if
                stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode) else "not a regular file")
        raise VolumeReadError(path, f"{what} is {kind}; only regular files are read", "Copy the data to a file first")
    return info


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", "rb") as handle:
            for line in handle:
                if line.startswith(b"MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _address_space_left() -> int | None:
    """What RLIMIT_AS still allows this process to map (None without a limit)."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    used = 0
    try:
        with open("/proc/self/status", "rb") as handle:
            for line in handle:
                if line.startswith(b"VmSize:"):
                    used = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    return max(soft - used, 0)


def memory_available() -> int:
    """Bytes this process can still allocate: free memory, bounded by an address-space limit if one is set."""
    if memory_override is not None:
        return int(memory_override)
    candidates = [v for v in (_meminfo_available(), _address_space_left()) if v is not None]
    if not candidates:
        try:
            candidates.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
        except (ValueError, OSError, AttributeError):
            candidates.append(16 << 30)
    return min(candidates)


def require_fits(path: Path, nbytes: int, what: str, *, copies: int = COPIES) -> None:
    """Refuse a declared size that would not fit in memory (with its working copies), quoting it in GiB."""
    available = memory_available()
    if nbytes < 0:
        raise CorruptFileError(path, f"{what} has a negative size")
    if nbytes * copies > available:
        raise VolumeReadError(
            path, f"{what} would need {gib(nbytes)} of memory; only {gib(available / copies)} can be used here",
            "The header may be damaged; if it is right, use a machine with more memory or crop the data first",
        )


def product(values) -> int:
    """Exact integer product (Python ints: no overflow for damaged headers)."""
    result = 1
    for value in values:
        result *= int(value)
    return result


def _decompressor(codec: str):
    if codec == "gzip":
        return zlib.decompressobj(16 + zlib.MAX_WBITS)
    if codec == "zlib":  # MetaImage: zlib (ITK) or gzip streams; 32 + wbits detects the header
        return zlib.decompressobj(32 + zlib.MAX_WBITS)
    if codec == "bzip2":
        return bz2.BZ2Decompressor()
    raise ValueError(f"unknown codec {codec!r}")


def inflate(source, codec: str, path: Path, *, limit: int, what: str = "the compressed data") -> bytearray:
    """Decompress all of ``source`` (bytes or a binary file) into at most ``limit`` bytes.

    Raises :class:`CorruptFileError` if the stream is damaged (CRC or format error), truncated, followed by
    garbage, or inflates beyond ``limit`` (the caller's expected size plus any slack it allows). Concatenated
    gzip members are accepted, as gzip itself does; NUL padding after the stream is ignored.
    """
    return inflate_prefix(source, codec, path, limit=limit, keep=limit, what=what)[0]


def inflate_prefix(source, codec: str, path: Path, *, limit: int, keep: int,
                   what: str = "the compressed data") -> tuple[bytearray, int]:
    """Like :func:`inflate`, but keep only the first ``keep`` bytes; returns them and the total inflated size.

    The whole stream is still decompressed (in chunks, never held in memory), so a CRC error or truncation at
    its end is found, and more than ``limit`` bytes in total is refused.
    """
    chunks = _chunks(source)
    output = bytearray()
    total = 0
    decompressor = _decompressor(codec)
    data = b""
    try:
        while True:
            more_output = codec == "bzip2" and not decompressor.needs_input
            if not data and not more_output:
                data = next(chunks, None)
                if data is None:
                    break
            piece = decompressor.decompress(data, min(limit - total + 1, CHUNK * 16))
            total += len(piece)
            if len(output) < keep:
                output += piece[: keep - len(output)]
            if total > limit:
                raise CorruptFileError(path, f"{what} inflates to more than the {limit} bytes expected",
                                       "The header and the data disagree; the file is damaged")
            data = b"" if codec == "bzip2" else decompressor.unconsumed_tail
            if decompressor.eof:
                rest = decompressor.unused_data
                if codec == "gzip" and rest.startswith(b"\x1f\x8b"):
                    decompressor, data = _decompressor(codec), rest  # another gzip member
                    continue
                if rest.strip(b"\0") or any(chunk.strip(b"\0") for chunk in chunks):
                    raise CorruptFileError(path, f"{what} is followed by unexpected bytes",
                                           "The file is damaged; re-export or re-copy it")
                return output, total
    except (zlib.error, OSError, EOFError, ValueError) as exc:
        raise CorruptFileError(path, f"{what} is damaged ({one_line(exc)})", "Re-export or re-copy the file") from exc
    raise CorruptFileError(path, f"{what} ends before the end of the compressed stream (truncated)",
                           "Re-export or re-copy the file")


def _chunks(source):
    if isinstance(source, (bytes, bytearray, memoryview)):
        view = memoryview(source)
        for start in range(0, len(view), CHUNK):
            yield bytes(view[start:start + CHUNK])
        return
    while True:
        chunk = source.read(CHUNK)
        if not chunk:
            return
        yield chunk


def header_lines(path: Path, *, limit: int = 8 << 20, stop=lambda line: False,
                 blank_ends: bool = True) -> tuple[list[bytes], int, bool]:
    """The text lines at the start of ``path`` up to a blank line (or ``stop(line)``), the byte offset after them,
    and whether a blank line (or ``stop``) ended them (False: the file ended first).

    Reads at most ``limit`` bytes: a binary file without line breaks is refused instead of read whole.
    """
    lines: list[bytes] = []
    offset = 0
    with open(path, "rb") as handle:
        while True:
            line = handle.readline(limit - offset + 1)
            if not line:
                return lines, offset, False
            offset += len(line)
            if offset > limit:
                raise CorruptFileError(path, f"no end of the header in the first {limit} bytes",
                                       "The file is not a valid header or is damaged")
            if not line.strip(b"\r\n"):
                if blank_ends:
                    return lines, offset, True
                continue
            lines.append(line)
            if stop(line):
                return lines, offset, True
