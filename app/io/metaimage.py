"""MetaImage (``.mha`` with local data, ``.mhd`` with a data file): header parsing and checks, and the writer.

The header is ``Key = Value`` lines ending with ``ElementDataFile``. Everything VTK's reader would trust is
checked here first (VTK aborts the process with ``std::bad_alloc`` on a ``DimSize`` of 100000^3 and reads all
zeros from a short or missing payload):

- ``NDims`` is 3, ``DimSize`` three positive integers whose voxels fit in memory, ``ElementType`` known,
  one channel, binary data, a byte order of ``True``/``False``;
- the data file is ``LOCAL`` or one regular file next to the header (``LIST`` and file patterns are refused);
- uncompressed data must be exactly the declared size after ``HeaderSize`` (``-1``: the data are the last
  bytes); compressed data must occupy exactly ``CompressedDataSize`` bytes when that is given, and must inflate
  to exactly the declared size, checksum included.

Geometry follows ITK's conventions (world coordinates are LPS; ``TransformMatrix`` lists the direction of each
axis in turn).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic import atomic_output, atomic_outputs, check_companions
from .errors import CorruptFileError, UnsupportedFormatError, VolumeReadError, VolumeWriteError
from .safety import header_lines, inflate_prefix, product, require_fits, require_regular_file

ELEMENT_TYPES = {"MET_CHAR": "i1", "MET_UCHAR": "u1", "MET_SHORT": "i2", "MET_USHORT": "u2", "MET_INT": "i4",
                 "MET_UINT": "u4", "MET_LONG": "i4", "MET_ULONG": "u4", "MET_LONG_LONG": "i8",
                 "MET_ULONG_LONG": "u8", "MET_FLOAT": "f4", "MET_DOUBLE": "f8"}


@dataclass
class MetaHeader:
    """The checked fields of a MetaImage header."""

    fields: dict[str, str]
    dims: tuple[int, int, int]
    dtype: np.dtype
    data_path: Path
    data_offset: int  # where the payload starts in data_path (after HeaderSize for external files)
    compressed: bool

    @property
    def nbytes(self) -> int:
        return product(self.dims) * self.dtype.itemsize


def _flag(fields: dict[str, str], names, default: bool, path: Path) -> bool:
    for name in names:
        if name in fields:
            value = fields[name].strip().lower()
            if value in ("true", "1"):
                return True
            if value in ("false", "0"):
                return False
            raise CorruptFileError(path, f"{name} must be True or False, got '{fields[name]}'")
    return default


def _int(fields: dict[str, str], name: str, path: Path, default: int | None = None) -> int:
    if name not in fields:
        if default is None:
            raise CorruptFileError(path, f"the MetaImage header lacks {name}")
        return default
    try:
        value = float(fields[name])
    except ValueError as exc:
        raise CorruptFileError(path, f"{name} is not a number ('{fields[name]}')") from exc
    if not np.isfinite(value) or value != int(value):
        raise CorruptFileError(path, f"{name} must be a whole number, got '{fields[name]}'")
    return int(value)


def parse_header(path) -> MetaHeader:
    """Read and check a MetaImage header and its payload's size (see the module notes)."""
    path = Path(path)
    size = require_regular_file(path).st_size
    lines, offset, _ = header_lines(path, limit=1 << 20, blank_ends=False,
                                    stop=lambda line: line.split(b"=", 1)[0].strip() == b"ElementDataFile")
    fields: dict[str, str] = {}
    for line in lines:
        text = line.decode("latin-1").strip()
        if "=" in text:
            key, value = text.split("=", 1)
            fields[key.strip()] = value.strip()
    if "NDims" not in fields or "DimSize" not in fields:
        raise CorruptFileError(path, "not a MetaImage header (NDims and DimSize are missing)")
    if "ElementDataFile" not in fields:
        raise CorruptFileError(path, "the MetaImage header has no ElementDataFile line (it may be truncated)")
    ndims = _int(fields, "NDims", path)
    if ndims != 3:
        raise UnsupportedFormatError(path, f"the image has {fields['NDims']} dimensions; Voxelscope needs 3")
    try:
        dims = tuple(int(v) for v in fields["DimSize"].split())
    except ValueError as exc:
        raise CorruptFileError(path, f"DimSize must be three integers, got '{fields['DimSize']}'") from exc
    if len(dims) != 3 or min(dims) < 1:
        raise CorruptFileError(path, f"DimSize must be three positive integers, got '{fields['DimSize']}'")
    if _int(fields, "ElementNumberOfChannels", path, 1) != 1:
        raise UnsupportedFormatError(path, "the image has several channels per voxel; Voxelscope needs grey values")
    element = fields.get("ElementType", "")
    if element not in ELEMENT_TYPES:
        raise UnsupportedFormatError(path, f"unknown ElementType '{element}'")
    if not _flag(fields, ("BinaryData",), True, path):
        raise UnsupportedFormatError(path, "ASCII MetaImage data (BinaryData = False) is not supported")
    msb = _flag(fields, ("BinaryDataByteOrderMSB", "ElementByteOrderMSB"), False, path)
    dtype = np.dtype(ELEMENT_TYPES[element]).newbyteorder(">" if msb else "<")
    compressed = _flag(fields, ("CompressedData",), False, path)
    header = MetaHeader(fields, dims, dtype, path, offset, compressed)
    require_fits(path, header.nbytes, f"an image of {'x'.join(map(str, dims))} {dtype.name} voxels")
    data_file = fields["ElementDataFile"]
    if data_file.upper() != "LOCAL":
        if data_file.upper().startswith("LIST") or "%" in data_file or len(data_file.split()) > 1:
            raise UnsupportedFormatError(path, f"MetaImage data split over several files ('{data_file}') is not "
                                               "supported", "Join the slices into one data file")
        header.data_path = Path(data_file) if Path(data_file).is_absolute() else path.parent / data_file
        if not header.data_path.exists():
            raise VolumeReadError(header.data_path, f"the data file named by {path.name} does not exist",
                                  "Keep the .mhd next to its data file")
        size = require_regular_file(header.data_path, f"the data file named by {path.name}").st_size
        header.data_offset = _int(fields, "HeaderSize", path, 0)
        if header.data_offset == -1:
            header.data_offset = size - header.nbytes if not compressed else 0
        if not 0 <= header.data_offset <= size:
            raise CorruptFileError(path, f"HeaderSize {fields.get('HeaderSize')} does not fit the data file")
    _check_payload(header, size)
    return header


def _check_payload(header: MetaHeader, size: int) -> None:
    data = header.data_path
    available = size - header.data_offset
    if not header.compressed:
        if available != header.nbytes:
            state = "truncated" if available < header.nbytes else "more data than the header declares"
            raise CorruptFileError(data, f"the pixel data holds {available} bytes but "
                                         f"{'x'.join(map(str, header.dims))} {header.dtype.name} voxels need "
                                         f"{header.nbytes} ({state})", "Re-export or re-copy the file")
        return
    if "CompressedDataSize" in header.fields:
        declared = _int(header.fields, "CompressedDataSize", data)
        if declared != available:
            raise CorruptFileError(data, f"CompressedDataSize is {declared} but {available} compressed bytes follow "
                                         "the header", "The file is damaged or truncated")
    with open(data, "rb") as handle:
        handle.seek(header.data_offset)
        _, total = inflate_prefix(handle, "zlib", data, limit=header.nbytes, keep=0, what="the compressed pixel data")
    if total != header.nbytes:
        raise CorruptFileError(data, f"the compressed pixel data inflates to {total} bytes but the image needs "
                                     f"{header.nbytes} (truncated)", "Re-export or re-copy the file")


def geometry(header: MetaHeader) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Axis vectors (columns, mm per voxel), origin (LPS) from the header, as ITK reads them."""
    fields, path = header.fields, header.data_path

    def numbers(text: str, count: int, what: str) -> np.ndarray:
        try:
            values = np.array([float(v) for v in text.split()])
        except ValueError as exc:
            raise CorruptFileError(path, f"{what} is not a list of numbers ('{text}')") from exc
        if values.size != count or not np.all(np.isfinite(values)):
            raise CorruptFileError(path, f"{what} must be {count} finite numbers, got '{text}'")
        return values

    spacing = numbers(fields.get("ElementSpacing", fields.get("ElementSize", "1 1 1")), 3, "ElementSpacing")
    origin = numbers(fields.get("Offset") or fields.get("Position") or fields.get("Origin") or "0 0 0", 3, "Offset")
    matrix = fields.get("TransformMatrix") or fields.get("Rotation") or fields.get("Orientation")
    direction = np.eye(3)
    if matrix:
        # ITK writes the direction of axis 0, then axis 1, then axis 2: the rows of the text are our columns.
        direction = numbers(matrix, 9, "TransformMatrix").reshape(3, 3).T
    return direction * spacing[None, :], origin, spacing


def write_metaimage(volume, path, *, overwrite: bool = False) -> Path:
    """Write a MetaImage with ITK's geometry conventions: ``.mha`` (one file) or ``.mhd`` (+ ``.zraw``).

    The data file of an ``.mhd`` is checked for overwriting before anything is written, and both files land
    together or not at all.
    """
    path = Path(path)
    array = np.ascontiguousarray(volume.array)
    types = {"i1": "MET_CHAR", "u1": "MET_UCHAR", "i2": "MET_SHORT", "u2": "MET_USHORT", "i4": "MET_INT",
             "u4": "MET_UINT", "i8": "MET_LONG_LONG", "u8": "MET_ULONG_LONG", "f4": "MET_FLOAT", "f8": "MET_DOUBLE"}
    code = array.dtype.str[1:]
    if code not in types:
        raise VolumeWriteError(f"{path}: MetaImage cannot store {array.dtype}")
    detached = path.suffix.lower() == ".mhd"
    data_path = path.with_suffix(".zraw")
    check_companions(path, [data_path] if detached else [], overwrite=overwrite)
    payload = zlib.compress(array.astype(array.dtype.newbyteorder("<")).tobytes(), 6)
    modality = {"CT": "MET_MOD_CT", "MR": "MET_MOD_MR"}.get(volume.modality)
    header = [
        "ObjectType = Image", "NDims = 3", "BinaryData = True", "BinaryDataByteOrderMSB = False",
        "CompressedData = True", f"CompressedDataSize = {len(payload)}",
        "TransformMatrix = " + " ".join(f"{v:.10g}" for v in volume.direction.T.ravel()),
        "Offset = " + " ".join(f"{v:.10g}" for v in volume.origin),
        "CenterOfRotation = 0 0 0", "AnatomicalOrientation = RAI",
        "ElementSpacing = " + " ".join(f"{v:.10g}" for v in volume.spacing),
        "DimSize = " + " ".join(str(n) for n in volume.dimensions),
    ]
    if modality:
        header.append(f"Modality = {modality}")
    header += [f"ElementType = {types[code]}", f"ElementDataFile = {data_path.name if detached else 'LOCAL'}"]
    text = ("\n".join(header) + "\n").encode("latin-1")
    if detached:
        with atomic_outputs([path, data_path], overwrite=overwrite) as (temporary, data_temporary):
            data_temporary.write_bytes(payload)
            temporary.write_bytes(text)
    else:
        with atomic_output(path, overwrite=overwrite) as temporary:
            temporary.write_bytes(text + payload)
    return path
