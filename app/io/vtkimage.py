"""Checks of VTK image files (XML ``.vti`` and legacy ``.vtk``) made before VTK's readers see them.

VTK's readers trust their headers: a ``WholeExtent`` of 100000^3 makes them allocate until ``std::bad_alloc``
aborts the process, and a damaged compressed block can come back as zeros. So the header is parsed here first:

- ``.vti``: the XML part (everything before ``<AppendedData``) is parsed with ElementTree; the file type, extents,
  origin, spacing and direction are checked, every data array's type and component count are known, the declared
  voxel count fits in memory, and every array's binary block (appended raw or base64, or inline base64/ASCII) is
  walked: its header must declare exactly ``tuples x components x item size`` bytes, compressed blocks
  (zlib, lzma) are inflated to check their sizes and checksums, and the blocks must lie inside the file;
- ``.vtk`` (legacy): the keyword header is read with a cap; ``DATASET STRUCTURED_POINTS`` with positive
  ``DIMENSIONS`` whose product equals ``POINT_DATA``, a known scalar type, and (binary files) enough bytes behind
  the ``LOOKUP_TABLE`` line; other datasets are refused by name.
"""

from __future__ import annotations

import base64
import binascii
import lzma
import re
import struct
import xml.etree.ElementTree as ElementTree
import zlib
from pathlib import Path

import numpy as np

from .errors import CorruptFileError, UnsupportedFormatError
from .safety import header_lines, one_line, product, require_fits, require_regular_file

_XML_TYPES = {"Int8": 1, "UInt8": 1, "Int16": 2, "UInt16": 2, "Int32": 4, "UInt32": 4, "Int64": 8, "UInt64": 8,
              "Float32": 4, "Float64": 8, "Char": 1, "UChar": 1, "Bit": 1, "IdType": 8, "String": 0}
_DATASETS = {"ImageData": "vtkImageData", "PolyData": "vtkPolyData", "UnstructuredGrid": "vtkUnstructuredGrid",
             "StructuredGrid": "vtkStructuredGrid", "RectilinearGrid": "vtkRectilinearGrid",
             "POLYDATA": "vtkPolyData", "UNSTRUCTURED_GRID": "vtkUnstructuredGrid",
             "STRUCTURED_GRID": "vtkStructuredGrid", "RECTILINEAR_GRID": "vtkRectilinearGrid",
             "STRUCTURED_POINTS": "vtkImageData", "FIELD": "vtkTable"}
_LEGACY_TYPES = {"bit": 1, "unsigned_char": 1, "char": 1, "unsigned_short": 2, "short": 2, "unsigned_int": 4,
                 "int": 4, "unsigned_long": 8, "long": 8, "float": 4, "double": 8, "vtktypeint64": 8,
                 "vtktypeuint64": 8, "vtkidtype": 8}
#: The XML part of a .vti with appended data is searched for in this many bytes at most.
_XML_HEADER_LIMIT = 16 << 20


def _not_an_image(path: Path, dataset: str) -> UnsupportedFormatError:
    kind = _DATASETS.get(dataset, dataset or "no dataset")
    return UnsupportedFormatError(path, f"the file holds {kind}, not an image volume",
                                  "Open meshes with Voxelscope's mesh reader (STL, OBJ, PLY, VTP, OFF); volumes "
                                  "need an image file")


# --------------------------------------------------------------------------------------------------------------
# XML image data (.vti)
# --------------------------------------------------------------------------------------------------------------
def _ints(text: str | None, count: int, path: Path, what: str) -> list[int]:
    try:
        values = [int(v) for v in (text or "").split()]
    except ValueError as exc:
        raise CorruptFileError(path, f"{what} is not a list of integers ('{text}')") from exc
    if len(values) != count:
        raise CorruptFileError(path, f"{what} must list {count} integers, got '{text}'")
    return values


def _floats(text: str | None, count: int, path: Path, what: str) -> None:
    if text is None:
        return
    try:
        values = [float(v) for v in text.split()]
    except ValueError as exc:
        raise CorruptFileError(path, f"{what} is not a list of numbers ('{text}')") from exc
    if len(values) != count or not all(np.isfinite(values)):
        raise CorruptFileError(path, f"{what} must be {count} finite numbers, got '{text}'")


def _xml_part(path: Path, size: int) -> tuple[str, int | None]:
    """The XML text before the appended data (closed so it parses) and the offset of the byte after '_'."""
    marker = b"<AppendedData"
    with open(path, "rb") as handle:
        head = handle.read(_XML_HEADER_LIMIT)
    at = head.find(marker)
    if at < 0:
        if size > len(head):
            require_fits(path, size, "the inline XML data")
            with open(path, "rb") as handle:
                head = handle.read()
        return head.decode("utf-8", "replace"), None
    end_tag = head.find(b">", at)
    underscore = head.find(b"_", end_tag)
    if end_tag < 0 or underscore < 0:
        raise CorruptFileError(path, "the <AppendedData> section has no '_' marker (the file is truncated)")
    encoding = re.search(rb'encoding\s*=\s*"([^"]*)"', head[at:end_tag])
    name = encoding.group(1).decode("ascii", "replace") if encoding else ""
    text = head[:at].decode("utf-8", "replace") + f'<AppendedData encoding="{name}"/></VTKFile>'
    return text, underscore + 1


class _Blocks:
    """Reads the binary block of one data array: VTK's size header, then raw or compressed bytes."""

    def __init__(self, path: Path, header_type: str, little: bool, compressor: str) -> None:
        self.path = path
        self.header_size = 8 if header_type == "UInt64" else 4
        self.format = ("<" if little else ">") + ("Q" if self.header_size == 8 else "I")
        self.compressor = compressor

    def _numbers(self, data: bytes, count: int) -> list[int]:
        if len(data) < count * self.header_size:
            raise CorruptFileError(self.path, "a data array's block header is truncated")
        return list(struct.unpack(self.format[0] + self.format[1] * count, data[: count * self.header_size]))

    def check(self, read_header, read_data, expected: int | None, what: str) -> None:
        """Walk one block; ``read_header(n)``/``read_data(n)`` return the next n decoded bytes."""
        if not self.compressor:
            (size,) = self._numbers(read_header(self.header_size), 1)
            if expected is not None and size != expected:
                raise CorruptFileError(self.path, f"{what} holds {size} bytes but its size needs {expected}")
            if len(read_data(size)) != size:
                raise CorruptFileError(self.path, f"{what} is truncated (the file ends inside it)")
            return
        blocks, block_size, last_size = self._numbers(read_header(3 * self.header_size), 3)
        if blocks > (1 << 24) or block_size > (1 << 31):
            raise CorruptFileError(self.path, f"{what} declares {blocks} compressed blocks of {block_size} bytes")
        sizes = self._numbers(read_header(blocks * self.header_size), blocks)
        total = 0 if blocks == 0 else (blocks - 1) * block_size + (last_size or block_size)
        if expected is not None and total != expected:
            raise CorruptFileError(self.path, f"{what} decompresses to {total} bytes but its size needs {expected}")
        if last_size > block_size:
            raise CorruptFileError(self.path, f"{what} has a last block larger than its block size")
        require_fits(self.path, total, what)
        for index, compressed in enumerate(sizes):
            data = read_data(compressed)
            if len(data) != compressed:
                raise CorruptFileError(self.path, f"{what} is truncated (the file ends inside it)")
            wanted = block_size if index < blocks - 1 or not last_size else last_size
            if "ZLib" in self.compressor:
                stream = zlib.decompressobj()
                try:
                    inflated = stream.decompress(data, wanted + 1)
                except zlib.error as exc:
                    raise CorruptFileError(self.path, f"{what} is damaged ({one_line(exc)})") from exc
                if not stream.eof or stream.unused_data:
                    raise CorruptFileError(self.path, f"{what} has a damaged compressed block")
            elif "LZMA" in self.compressor:
                try:
                    inflated = lzma.decompress(data)
                except lzma.LZMAError as exc:
                    raise CorruptFileError(self.path, f"{what} is damaged ({one_line(exc)})") from exc
            else:  # LZ4: no decoder here; the sizes were checked
                continue
            if len(inflated) != wanted:
                raise CorruptFileError(self.path, f"{what} has a block of {len(inflated)} bytes where {wanted} are "
                                                  "declared")


class _Base64Reader:
    """Decodes base64 text piecewise (VTK encodes a compressed block's header apart from its data)."""

    def __init__(self, text: bytes, path: Path) -> None:
        self.text = re.sub(rb"\s+", b"", text)
        self.position = 0
        self.path = path

    def take(self, count: int) -> bytes:
        """Decode a separately encoded piece of ``count`` bytes."""
        chars = 4 * -(-count // 3)
        piece = self.text[self.position:self.position + chars]
        self.position += chars
        try:
            return base64.b64decode(piece, validate=True)[:count]
        except (binascii.Error, ValueError) as exc:
            raise CorruptFileError(self.path, f"base64 data is damaged ({one_line(exc)})") from exc


def check_vti(path) -> None:
    """Refuse a ``.vti`` file whose header or data blocks do not match (see the module notes)."""
    check_vtk_xml(path, "ImageData")


def check_vtk_xml(path, expected: str) -> None:
    """Check a VTK XML file of type ``expected`` ("ImageData" or "PolyData") before VTK's reader sees it."""
    path = Path(path)
    size = require_regular_file(path).st_size
    text, appended_start = _xml_part(path, size)
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise CorruptFileError(path, f"the XML header is malformed ({one_line(exc)})", "The file is damaged") from exc
    if root.tag != "VTKFile":
        raise CorruptFileError(path, f"not a VTK XML file (root element <{root.tag}>)")
    kind = root.get("type", "")
    if kind != expected:
        if expected == "ImageData":
            raise _not_an_image(path, kind)
        raise UnsupportedFormatError(path, f"the file holds {_DATASETS.get(kind, kind or 'no dataset')}, not a "
                                           "surface mesh (vtkPolyData)")
    byte_order = root.get("byte_order", "LittleEndian")
    if byte_order not in ("LittleEndian", "BigEndian"):
        raise CorruptFileError(path, f"unknown byte_order '{byte_order}'")
    header_type = root.get("header_type", "UInt32")
    if header_type not in ("UInt32", "UInt64"):
        raise CorruptFileError(path, f"unknown header_type '{header_type}'")
    compressor = root.get("compressor", "")
    if compressor and compressor not in ("vtkZLibDataCompressor", "vtkLZ4DataCompressor", "vtkLZMADataCompressor"):
        raise UnsupportedFormatError(path, f"unknown compressor '{compressor}'")
    dataset = root.find(expected)
    if dataset is None:
        raise CorruptFileError(path, f"the file has no <{expected}> element")
    blocks = _Blocks(path, header_type, byte_order == "LittleEndian", compressor)
    appended = root.find("AppendedData")
    encoding = appended.get("encoding", "raw") if appended is not None else None
    pieces = dataset.findall("Piece")
    if not pieces:
        raise CorruptFileError(path, f"the {expected} has no <Piece> (no data)")
    check = (lambda array, tuples: _check_array(path, array, tuples, blocks, encoding, appended_start, size))
    if expected == "ImageData":
        _check_image_pieces(path, dataset, pieces, check)
    else:
        _check_poly_pieces(path, pieces, check)
    for array in dataset.findall("FieldData/Array") + dataset.findall("FieldData/DataArray"):
        check(array, None)
    if appended_start is not None:
        _check_tail(path, size)


def _check_tail(path: Path, size: int) -> None:
    """Appended data must be followed by the closing tags: anything else means the file was cut."""
    with open(path, "rb") as handle:
        handle.seek(max(size - 256, 0))
        tail = handle.read().rstrip()
    if not tail.endswith(b"</VTKFile>") or b"</AppendedData>" not in tail:
        raise CorruptFileError(path, "the file does not end with </AppendedData></VTKFile> (it is truncated)",
                               "Re-export or re-copy it")


def _check_image_pieces(path: Path, image, pieces, check) -> None:
    whole = _ints(image.get("WholeExtent"), 6, path, "WholeExtent")
    dims = [whole[1] - whole[0] + 1, whole[3] - whole[2] + 1, whole[5] - whole[4] + 1]
    if min(dims) < 1:
        raise CorruptFileError(path, f"WholeExtent {' '.join(map(str, whole))} is empty or inverted")
    _floats(image.get("Origin"), 3, path, "Origin")
    _floats(image.get("Spacing"), 3, path, "Spacing")
    _floats(image.get("Direction"), 9, path, "Direction")
    require_fits(path, product(dims) * 8, f"an image of {'x'.join(map(str, dims))} voxels", copies=1)
    for piece in pieces:
        extent = _ints(piece.get("Extent"), 6, path, "the piece Extent")
        if any(extent[2 * a] < whole[2 * a] or extent[2 * a + 1] > whole[2 * a + 1] or extent[2 * a] > extent[2 * a + 1]
               for a in range(3)):
            raise CorruptFileError(path, f"the piece Extent {' '.join(map(str, extent))} lies outside WholeExtent")
        points = product(extent[2 * a + 1] - extent[2 * a] + 1 for a in range(3))
        cells = product(max(extent[2 * a + 1] - extent[2 * a], 1) for a in range(3))
        for section, tuples in (("PointData", points), ("CellData", cells)):
            for array in piece.findall(f"{section}/DataArray"):
                check(array, tuples)


def _check_poly_pieces(path: Path, pieces, check) -> None:
    for piece in pieces:
        counts = {}
        for name in ("NumberOfPoints", "NumberOfVerts", "NumberOfLines", "NumberOfStrips", "NumberOfPolys"):
            (counts[name],) = _ints(piece.get(name, "0"), 1, path, name)
            if counts[name] < 0:
                raise CorruptFileError(path, f"{name} is negative ({counts[name]})")
        points = counts["NumberOfPoints"]
        cells = sum(v for k, v in counts.items() if k != "NumberOfPoints")
        require_fits(path, points * 24 + cells * 32, f"a mesh of {points} points and {cells} cells")
        for array in piece.findall("Points/DataArray"):
            if array.get("NumberOfComponents", "1") != "3":
                raise CorruptFileError(path, "the Points array does not have 3 components")
            check(array, points)
        for section, tuples in (("PointData", points), ("CellData", cells)):
            for array in piece.findall(f"{section}/DataArray"):
                check(array, tuples)
        for section in ("Verts", "Lines", "Strips", "Polys"):
            for array in piece.findall(f"{section}/DataArray"):
                check(array, None)


def _check_array(path: Path, array, tuples: int | None, blocks: _Blocks, encoding, appended_start, size: int) -> None:
    name = array.get("Name", "unnamed")
    what = f"the data array '{name}'"
    kind = array.get("type", "")
    if kind not in _XML_TYPES or (kind == "String" and tuples is not None):
        raise UnsupportedFormatError(path, f"{what} has the unsupported type '{kind}'")
    try:
        components = int(array.get("NumberOfComponents", "1"))
    except ValueError as exc:
        raise CorruptFileError(path, f"{what} has an invalid NumberOfComponents") from exc
    if not 1 <= components <= 64:
        raise CorruptFileError(path, f"{what} has {components} components")
    expected = None if tuples is None else tuples * components * _XML_TYPES[kind]
    if expected is not None:
        require_fits(path, expected, what)
    fmt = array.get("format", "ascii")
    if fmt == "appended":
        if appended_start is None or encoding not in ("raw", "base64"):
            raise CorruptFileError(path, f"{what} is appended but the file has no usable <AppendedData>")
        try:
            offset = int(array.get("offset", ""))
        except ValueError as exc:
            raise CorruptFileError(path, f"{what} has an invalid offset") from exc
        if not 0 <= offset < size - appended_start:
            raise CorruptFileError(path, f"{what} starts at offset {offset}, outside the appended data")
        with open(path, "rb") as handle:
            handle.seek(appended_start + offset)
            if encoding == "raw":
                def bounded(count: int) -> bytes:  # a damaged size must not make Python allocate it
                    return handle.read(max(0, min(count, size - handle.tell())))

                blocks.check(bounded, bounded, expected, what)
            else:
                wanted = size if expected is None else 4 * -(-(expected + blocks.header_size * 64) // 3) + (8 << 20)
                text = handle.read(min(wanted, size))
                reader = _Base64Reader(text.split(b"<", 1)[0], path)
                _check_base64(reader, blocks, expected, what)
    elif fmt == "binary":
        reader = _Base64Reader((array.text or "").encode("ascii", "replace"), path)
        _check_base64(reader, blocks, expected, what)
    elif fmt == "ascii":
        values = (array.text or "").split()
        if tuples is not None and len(values) != tuples * components:
            raise CorruptFileError(path, f"{what} lists {len(values)} values but {tuples * components} are needed")
    else:
        raise CorruptFileError(path, f"{what} has the unknown format '{fmt}'")


def _check_base64(reader: _Base64Reader, blocks: _Blocks, expected: int | None, what: str) -> None:
    if blocks.compressor:
        blocks.check(reader.take, lambda n: reader.take(n) if n else b"", expected, what)
        return
    # Uncompressed: VTK encodes the size header and the data together in one base64 stream.
    start = reader.position
    head = reader.text[start:start + 4 * -(-blocks.header_size // 3) + 4]
    try:
        (size,) = blocks._numbers(base64.b64decode(head[: len(head) - len(head) % 4] or b"", validate=False), 1)
    except (binascii.Error, ValueError) as exc:
        raise CorruptFileError(reader.path, f"{what} has damaged base64 data ({one_line(exc)})") from exc
    if size > (len(reader.text) - start) * 3 // 4:
        raise CorruptFileError(reader.path, f"{what} declares {size} bytes, more than the file holds (truncated)")
    chars = reader.text[start:start + 4 * -(-(blocks.header_size + size) // 3)]
    try:
        decoded = base64.b64decode(chars, validate=True)
    except (binascii.Error, ValueError) as exc:
        raise CorruptFileError(reader.path, f"{what} has damaged base64 data ({one_line(exc)})") from exc
    blocks.check(lambda n: decoded[:n], lambda n: decoded[blocks.header_size:blocks.header_size + n], expected, what)


# --------------------------------------------------------------------------------------------------------------
# Legacy VTK (.vtk)
# --------------------------------------------------------------------------------------------------------------
def check_legacy_vtk(path) -> None:
    """Refuse a legacy ``.vtk`` file that is not a consistent STRUCTURED_POINTS image (see the module notes)."""
    path = Path(path)
    size = require_regular_file(path).st_size
    lines, offset, _ = header_lines(path, limit=1 << 20, stop=lambda line: line.upper().startswith(b"LOOKUP_TABLE"), blank_ends=False)
    if not lines or not lines[0].lower().startswith(b"# vtk datafile"):
        raise CorruptFileError(path, "not a legacy VTK file (no '# vtk DataFile' line)")
    # Line 2 is a title (blank lines are skipped, so an empty title leaves the mode on line 2), then the mode.
    modes = [i for i in (1, 2) if i < len(lines) and lines[i].strip().upper() in (b"ASCII", b"BINARY")]
    if not modes:
        raise CorruptFileError(path, "the legacy VTK header has no ASCII or BINARY line where it should")
    mode = lines[modes[-1]].strip().upper()
    fields: dict[str, list[str]] = {}
    for line in lines[modes[-1] + 1:]:
        words = line.decode("latin-1").split()
        if words:
            fields.setdefault(words[0].upper(), words[1:])
    dataset = (fields.get("DATASET") or [""])[0].upper()
    if dataset != "STRUCTURED_POINTS":
        raise _not_an_image(path, dataset)
    dims = _ints(" ".join(fields.get("DIMENSIONS", [])), 3, path, "DIMENSIONS")
    if min(dims) < 1:
        raise CorruptFileError(path, f"DIMENSIONS {' '.join(map(str, dims))} must be positive")
    for key in ("SPACING", "ASPECT_RATIO", "ORIGIN"):
        if key in fields:
            _floats(" ".join(fields[key]), 3, path, key)
    points = product(dims)
    if "POINT_DATA" not in fields:
        raise CorruptFileError(path, "the file has no POINT_DATA section")
    (declared,) = _ints(" ".join(fields["POINT_DATA"][:1]), 1, path, "POINT_DATA")
    if declared != points:
        raise CorruptFileError(path, f"POINT_DATA {declared} does not match DIMENSIONS "
                                     f"{'x'.join(map(str, dims))} ({points} points)")
    scalars = fields.get("SCALARS")
    if not scalars or len(scalars) < 2:
        raise CorruptFileError(path, "the file has no SCALARS point data")
    item = _LEGACY_TYPES.get(scalars[1].lower())
    if item is None:
        raise UnsupportedFormatError(path, f"unknown scalar type '{scalars[1]}'")
    components = int(scalars[2]) if len(scalars) > 2 and scalars[2].isdigit() else 1
    if not 1 <= components <= 4:
        raise CorruptFileError(path, f"SCALARS has {components} components")
    require_fits(path, points * components * max(item, 4), f"an image of {'x'.join(map(str, dims))} voxels")
    if not lines[-1].upper().startswith(b"LOOKUP_TABLE"):
        raise CorruptFileError(path, "the SCALARS section has no LOOKUP_TABLE line (the file is truncated)")
    needed = points * components * (item if scalars[1].lower() != "bit" else 1)
    if mode == b"BINARY":
        if scalars[1].lower() == "bit":
            needed = -(-points * components // 8)
        if size - offset < needed:
            raise CorruptFileError(path, f"the binary scalars hold {size - offset} bytes but {needed} are needed "
                                         "(truncated)", "Re-export or re-copy it")
        with open(path, "rb") as handle:
            handle.seek(offset + needed)
            rest = handle.read(4096).lstrip()
        if rest and not re.match(rb"[A-Z_]{4,}", rest):  # only another section may follow the scalars
            raise CorruptFileError(path, f"{size - offset - needed} bytes follow the declared scalars; the header "
                                         "declares less data than the file holds", "The file is damaged")
        return
    require_fits(path, (size - offset) * 8, "the ASCII scalars")
    with open(path, "rb") as handle:
        handle.seek(offset)
        tokens = handle.read().split()
    values = next((i for i, token in enumerate(tokens) if token[:1].isalpha() and token.upper() == token
                   and not token[:3].lower() in (b"nan", b"inf")), len(tokens))
    if values != points * components:
        state = "truncated" if values < points * components else "more values than declared"
        raise CorruptFileError(path, f"the ASCII scalars hold {values} values but {points * components} are "
                                     f"needed ({state})", "Re-export or re-copy it")
