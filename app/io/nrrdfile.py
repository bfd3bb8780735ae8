"""NRRD (``.nrrd`` attached, ``.nhdr`` detached): header parsed by pynrrd, data read and checked here.

pynrrd (the well-kept library for the format) parses and types the header fields and refuses malformed vectors and
matrices. Reading the data is done here rather than by ``nrrd.read_data``, which reads whole data files with no
size cap, skips lines one ``readline`` at a time and does not check the end of a gzip stream:

- the header is read with a cap (8 MiB), the data file must be a regular file (never a FIFO or ``/dev/zero``);
- ``line skip`` (>= 0) skips lines of the data file (or of the bytes after an attached header) before anything
  else, and is refused if the data has fewer lines;
- ``byte skip`` >= 0 skips bytes before the data; -1 means "the data are the last bytes": for raw data the last
  bytes of the file, for gzip/bzip2 the last bytes of the *decompressed* stream (as pynrrd reads pynrrd's
  ``BallBinary30x30x30_byteskip_minus_one_nifti.nhdr``, a gzipped NIfTI file behind a NRRD header); other negative
  values are refused;
- raw data must be exactly the declared size after the skips (fewer bytes: truncated; more: damaged), compressed
  streams are inflated with a cap and must end cleanly (CRC checked), ASCII data must hold exactly the declared
  number of values;
- ``endian`` is ``little`` or ``big`` (needed for multi-byte types outside ASCII); anything else is refused.

Geometry is converted here (space, space directions, space origin, spacings) to LPS; spaces LPS, RAS, LAS and
scanner-xyz (taken as LPS) are supported; one leading non-spatial axis (components) keeps its first component.
"""

from __future__ import annotations

import gzip
import warnings
from pathlib import Path

import numpy as np

from .atomic import atomic_output
from .errors import CorruptFileError, UnsupportedFormatError, VolumeReadError, VolumeWriteError
from .geometry import LPS_FROM_RAS, guess_ct, make_volume, modality_from_description, orthonormal_direction
from .safety import CHUNK, header_lines, inflate, one_line, product, require_fits, require_regular_file

_NRRD_TYPES = {
    "signed char": "i1", "int8": "i1", "int8_t": "i1", "uchar": "u1", "unsigned char": "u1", "uint8": "u1",
    "uint8_t": "u1", "short": "i2", "short int": "i2", "signed short": "i2", "signed short int": "i2", "int16": "i2",
    "int16_t": "i2", "ushort": "u2", "unsigned short": "u2", "unsigned short int": "u2", "uint16": "u2",
    "uint16_t": "u2", "int": "i4", "signed int": "i4", "int32": "i4", "int32_t": "i4", "uint": "u4",
    "unsigned int": "u4", "uint32": "u4", "uint32_t": "u4", "longlong": "i8", "long long": "i8", "long long int": "i8",
    "signed long long": "i8", "signed long long int": "i8", "int64": "i8", "int64_t": "i8", "ulonglong": "u8",
    "unsigned long long": "u8", "unsigned long long int": "u8", "uint64": "u8", "uint64_t": "u8",
    "float": "f4", "double": "f8",
}
_SPACES = {
    "left-posterior-superior": np.eye(3), "lps": np.eye(3),
    "right-anterior-superior": LPS_FROM_RAS, "ras": LPS_FROM_RAS,
    "left-anterior-superior": np.diag([1.0, -1.0, 1.0]), "las": np.diag([1.0, -1.0, 1.0]),
    "scanner-xyz": np.eye(3), "3d-right-handed": np.eye(3),
}
_ENCODINGS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2", "ascii": "ascii",
              "text": "ascii", "txt": "ascii"}
#: With ``byte skip: -1`` on compressed data the stream may hold this much before the data (a header, as in a
#: gzipped NIfTI file).
_SKIP_SLACK = 64 << 20


def _parse_header(path: Path, warn: list[str]) -> tuple[dict, int | None]:
    """The typed header fields, and the offset of attached data (None when no blank line ends the header)."""
    import nrrd

    lines, offset, ended = header_lines(path)
    if not lines or not lines[0].startswith(b"NRRD000"):
        raise CorruptFileError(path, "the file does not start with the NRRD magic 'NRRD000x'")
    text = [line.decode("latin-1") for line in lines]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            header = nrrd.read_header(text)
        except Exception as exc:  # NRRDError, ValueError from number parsing, unpacking of lines without ':'
            raise CorruptFileError(path, f"invalid NRRD header ({type(exc).__name__}: {one_line(exc)})",
                                   "Fix or re-export the header") from exc
    warn.extend(f"{path.name}: {one_line(w.message)}" for w in caught)
    return dict(header), offset if ended else None


def _field(header: dict, *names, default=None):
    for name in names:
        if name in header:
            return header[name]
    return default


def _dtype(header: dict, encoding: str, path: Path) -> np.dtype:
    type_name = str(header.get("type", "")).lower()
    if type_name not in _NRRD_TYPES:
        raise UnsupportedFormatError(path, f"unsupported NRRD type '{header.get('type')}'")
    dtype = np.dtype(_NRRD_TYPES[type_name])
    if dtype.itemsize > 1 and encoding != "ascii":
        endian = str(header.get("endian", "")).lower()
        if endian not in ("little", "big"):
            raise CorruptFileError(path, f"invalid NRRD endian '{header.get('endian', '')}'; it must be 'little' or "
                                         "'big' for this type", "Fix the header")
        dtype = dtype.newbyteorder("<" if endian == "little" else ">")
    return dtype


def _geometry(header: dict, sizes: list[int], path: Path, warn: list[str]):
    """Spatial axes, spacing, direction and origin (LPS) from the header."""
    dimension = len(sizes)
    kinds = [str(k).lower() for k in header.get("kinds", [])]
    if kinds and len(kinds) != dimension:
        raise CorruptFileError(path, f"'kinds' lists {len(kinds)} values for dimension {dimension}")
    spatial = [i for i in range(dimension) if not kinds or kinds[i] in ("domain", "space", "???", "none")]
    directions = None
    if "space directions" in header:
        vectors = np.asarray(header["space directions"], dtype=np.float64)
        if vectors.ndim != 2 or vectors.shape[0] != dimension:
            raise CorruptFileError(path, "'space directions' does not list one entry per axis")
        if vectors.shape[1] != 3:
            raise UnsupportedFormatError(path, f"the NRRD space has {vectors.shape[1]} dimensions; Voxelscope needs 3")
        spatial = [i for i in range(dimension) if not np.all(np.isnan(vectors[i]))]
        if len(spatial) == 3:
            directions = np.column_stack([vectors[i] for i in spatial])
    if len(spatial) != 3 or dimension > 4:
        raise UnsupportedFormatError(path, f"the NRRD has {len(spatial)} spatial axes; Voxelscope needs exactly three")
    non_spatial = [i for i in range(dimension) if i not in spatial]
    if non_spatial and non_spatial[0] != 0:
        if sizes[non_spatial[0]] > 1:
            raise UnsupportedFormatError(path, "only a leading non-spatial (component) axis is supported")
    space_name = str(header.get("space", "")).lower()
    to_lps = _SPACES.get(space_name)
    if space_name and to_lps is None:
        raise UnsupportedFormatError(path, f"unsupported NRRD space '{header['space']}'")
    if to_lps is None:
        to_lps = np.eye(3)
        if directions is None:
            warn.append(f"{path.name}: no 'space' field; coordinates taken as LPS")
    if directions is None:
        spacings = header.get("spacings")
        values = [1.0] * dimension
        if spacings is not None:
            spacings = np.asarray(spacings, dtype=np.float64).reshape(-1)
            if spacings.size != dimension:
                raise CorruptFileError(path, "'spacings' does not list one value per axis")
            values = [float(v) if np.isfinite(v) else 1.0 for v in spacings]
        else:
            warn.append(f"{path.name}: no spacing in the header; 1 mm assumed")
        directions = np.diag([values[i] for i in spatial])
    origin = header.get("space origin")
    if origin is None:
        origin = np.zeros(3)
    origin = np.asarray(origin, dtype=np.float64).reshape(-1)
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        raise CorruptFileError(path, f"'space origin' must be three finite numbers, got {origin.tolist()}")
    spacing, direction = orthonormal_direction(to_lps @ directions, path, warn)
    return spatial, non_spatial, spacing, direction, to_lps @ origin


def _skip_lines(handle, count: int, path: Path) -> None:
    """Skip ``count`` lines by scanning chunks for newlines (bounded by the file's size, never one line at a time)."""
    left = count
    while left > 0:
        position = handle.tell()
        chunk = handle.read(CHUNK)
        if not chunk:
            raise CorruptFileError(path, f"'line skip: {count}' skips more lines than the data holds",
                                   "The header is damaged")
        newlines = chunk.count(b"\n")
        if newlines < left:
            left -= newlines
            continue
        index = -1
        for _ in range(left):
            index = chunk.index(b"\n", index + 1)
        handle.seek(position + index + 1)
        left = 0


def _data_source(header: dict, path: Path, attached_offset: int | None) -> tuple[Path, int]:
    """The file holding the data and the offset where it starts (before line and byte skips)."""
    data_file = _field(header, "data file", "datafile")
    if data_file is None:
        if attached_offset is None:
            raise CorruptFileError(path, "the NRRD header has no terminating blank line and names no data file",
                                   "The file may be truncated")
        return path, attached_offset
    data_file = str(data_file).strip()
    if data_file.upper().startswith("LIST") or len(data_file.split()) > 1 or "%" in data_file:
        raise UnsupportedFormatError(path, "NRRD data split over several files is not supported",
                                     "Join the files into one data file")
    data_path = Path(data_file) if Path(data_file).is_absolute() else path.parent / data_file
    if not data_path.exists():
        raise VolumeReadError(data_path, f"the data file named by {path.name} cannot be read (it does not exist)",
                              "Keep the .nhdr next to its data file")
    require_regular_file(data_path, f"the data file named by {path.name}")
    return data_path, 0


def _read_payload(header: dict, encoding: str, dtype: np.dtype, count: int, source: Path, start: int,
                  path: Path) -> np.ndarray:
    """The ``count`` values of the data, with line and byte skips applied and the size checked exactly."""
    line_skip = int(_field(header, "line skip", "lineskip", default=0))
    byte_skip = int(_field(header, "byte skip", "byteskip", default=0))
    if line_skip < 0:
        raise CorruptFileError(path, f"'line skip: {line_skip}' is negative", "Fix the header")
    if byte_skip < -1:
        raise CorruptFileError(path, f"'byte skip: {byte_skip}' is invalid (it must be -1 or more)", "Fix the header")
    expected = count * dtype.itemsize
    require_fits(path, expected, f"the declared {count} voxels of {dtype.name}")
    size = source.stat().st_size
    with open(source, "rb") as handle:
        handle.seek(start)
        if line_skip:
            _skip_lines(handle, line_skip, source)
        start = handle.tell()
        available = size - start
        name = source.name
        if encoding == "raw":
            if byte_skip == -1:
                if available < expected:
                    raise CorruptFileError(source, f"the data holds {available} bytes but the header needs {expected}",
                                           "The file is truncated; re-export or re-copy it")
                offset = size - expected
            else:
                offset = start + byte_skip
                if size - offset != expected:
                    state = "truncated" if size - offset < expected else "more data than the header declares"
                    raise CorruptFileError(source, f"the data holds {max(size - offset, 0)} bytes after the skips but "
                                                   f"the header needs {expected} ({state})", "Re-export or re-copy it")
            return np.fromfile(source, dtype=dtype, count=count, offset=offset)
        if encoding == "ascii":
            if available > 64 * max(count, 1) + (1 << 20):
                raise CorruptFileError(source, f"the ASCII data ({available} bytes) is far longer than {count} values")
            text = handle.read()[max(byte_skip, 0):]
            try:
                values = np.array(text.split(), dtype=np.float64)
            except ValueError as exc:
                raise CorruptFileError(source, f"the ASCII data holds something that is not a number in {name}") from exc
            if values.size != count:
                raise CorruptFileError(source, f"the ASCII data holds {values.size} values but the header declares "
                                               f"{count}", "The file is damaged or truncated")
            return values.astype(dtype)
        limit = expected + (_SKIP_SLACK if byte_skip == -1 else byte_skip)
        data = inflate(handle, encoding, source, limit=limit, what=f"the {encoding} data")
    if byte_skip == -1:
        if len(data) < expected:
            raise CorruptFileError(source, f"the {encoding} data inflates to {len(data)} bytes but the header needs "
                                           f"{expected} (truncated)", "Re-export or re-copy it")
        data = memoryview(data)[len(data) - expected:]
    elif len(data) != byte_skip + expected:
        raise CorruptFileError(source, f"the {encoding} data inflates to {len(data)} bytes but the header needs "
                                       f"{byte_skip + expected} (truncated)", "Re-export or re-copy it")
    else:
        data = memoryview(data)[byte_skip:]
    return np.frombuffer(data, dtype=dtype, count=count)


def read_nrrd(path):
    """NRRD with attached (``.nrrd``) or detached (``.nhdr``) data (see the module notes for what is checked)."""
    path = Path(path)
    warn: list[str] = []
    require_regular_file(path)
    header, offset = _parse_header(path, warn)
    for name in ("type", "dimension", "sizes", "encoding"):
        if name not in header:
            raise CorruptFileError(path, f"the NRRD header lacks the required field '{name}'")
    sizes = [int(v) for v in np.asarray(header["sizes"]).reshape(-1)]
    dimension = int(header["dimension"])
    if len(sizes) != dimension:
        raise CorruptFileError(path, f"'sizes' lists {len(sizes)} values for dimension {dimension}")
    if any(n < 1 for n in sizes):
        raise CorruptFileError(path, f"'sizes' must be positive, got {' '.join(map(str, sizes))}")
    encoding = _ENCODINGS.get(str(header["encoding"]).lower())
    if encoding is None:
        raise UnsupportedFormatError(path, f"unsupported NRRD encoding '{header['encoding']}'")
    dtype = _dtype(header, encoding, path)
    spatial, non_spatial, spacing, direction, origin = _geometry(header, sizes, path, warn)
    source, start = _data_source(header, path, offset)
    count = product(sizes)
    values = _read_payload(header, encoding, dtype, count, source, start, path)
    values = values.astype(dtype.newbyteorder("="), copy=False).reshape(sizes[::-1])  # NRRD's first axis is fastest
    if non_spatial:
        if sizes[non_spatial[0]] > 1:
            warn.append(f"{path.name}: {sizes[non_spatial[0]]} components per voxel; the first one is shown")
        values = values[..., 0]
    modality, units = modality_from_description(str(header.get("content", "")))
    if not modality:
        modality, units = guess_ct(values, warn, path)
    return make_volume(values, spacing, origin, direction, path, "NRRD", warn, modality, units)


def write_nrrd(volume, path, *, overwrite: bool = False) -> Path:
    """Write an attached-header NRRD in LPS space with gzip encoding."""
    path = Path(path)
    array = np.ascontiguousarray(volume.array)
    names = {"i1": "int8", "u1": "uint8", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint", "i8": "int64",
             "u8": "uint64", "f4": "float", "f8": "double"}
    code = array.dtype.str[1:]
    if code not in names:
        raise VolumeWriteError(f"{path}: NRRD cannot store {array.dtype}")
    axes = volume.direction * np.asarray(volume.spacing)[None, :]
    directions = " ".join("(" + ",".join(f"{v:.10g}" for v in axes[:, c]) + ")" for c in range(3))
    header = (
        "NRRD0004\n# Written by Voxelscope\n"
        f"type: {names[code]}\ndimension: 3\nspace: left-posterior-superior\n"
        f"sizes: {' '.join(str(n) for n in volume.dimensions)}\n"
        f"space directions: {directions}\nkinds: domain domain domain\n"
        f"endian: {'little' if array.dtype.byteorder in '<=|' else 'big'}\nencoding: gzip\n"
        f"space origin: ({','.join(f'{v:.10g}' for v in volume.origin)})\n"
        f"content: modality={volume.modality};units={volume.units}\n\n"
    )
    with atomic_output(path, overwrite=overwrite) as temporary:
        with open(temporary, "wb") as handle:
            handle.write(header.encode("latin-1"))
            with gzip.GzipFile(filename="", fileobj=handle, mode="wb", compresslevel=6, mtime=0) as stream:
                stream.write(memoryview(array).cast("B"))
    return path
