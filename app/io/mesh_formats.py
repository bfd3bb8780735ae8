"""What a mesh file is and whether it is whole: format sniffing and per-format checks made before VTK reads it.

VTK's mesh readers accept damaged files silently: a truncated ASCII PLY comes back with invented vertices, an OBJ
face naming vertex 5 of 3 becomes a cell pointing outside the points, a binary STL whose header declares more
triangles than the file holds reads a fraction of them. So each file is checked here first:

- STL: binary when the size is exactly ``84 + 50 * count`` (the count in bytes 80-84); text starting with
  ``solid`` is ASCII and must end with ``endsolid`` with three ``vertex`` lines per ``facet``; anything else is
  a binary STL whose declared count does not match its size (truncated or padded) or not an STL at all;
- OBJ: text; every face index (1-based, or negative = relative) must name a vertex that exists;
- PLY: the header's elements and properties are parsed; the body must hold exactly the declared rows (ASCII:
  one line per row with the right number of values; binary: the exact byte count, list lengths walked);
- OFF: parsed here (:func:`read_off`): keyword, counts, vertices, faces of 3 or more indices in range;
- VTP: the XML header and every data block are checked like a ``.vti`` (:func:`app.io.vtkimage.check_vtk_xml`).

Every failure is a :class:`MeshReadError` whose one-line message names the file.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np

from .errors import MeshReadError
from .safety import require_fits

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_OBJ_KEYWORDS = {b"v", b"vt", b"vn", b"vp", b"f", b"l", b"p", b"o", b"g", b"s", b"usemtl", b"mtllib", b"#", b"cstype",
                 b"deg", b"curv", b"surf", b"parm", b"end", b"mg", b"lod", b"shadow_obj", b"trace_obj", b"bevel",
                 b"c_interp", b"d_interp", b"ctech", b"stech", b"con", b"sp", b"trim", b"hole", b"scrv", b"bmat",
                 b"step", b"curv2", b"call", b"csh"}


def sniff(path: Path) -> str | None:
    """The format the content looks like: "STL", "PLY", "VTP", "OFF", "OBJ", or None (unknown/binary)."""
    size = path.stat().st_size
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if head.startswith(b"ply\n") or head.startswith(b"ply\r\n"):
        return "PLY"
    stripped = head.lstrip()
    if stripped.startswith(b"<?xml") or stripped.startswith(b"<VTKFile"):
        return "VTP"
    if size >= 84 and 84 + 50 * struct.unpack("<I", head[80:84])[0] == size:
        return "STL"
    if stripped[:5].lower() == b"solid":
        return "STL"
    first = next((line.split(b"#")[0].split() for line in head.splitlines() if line.split(b"#")[0].strip()), [])
    if first and re.fullmatch(rb"[A-Z]*OFF", first[0]):
        return "OFF"
    if b"\0" in head:
        return None
    words = [line.split(None, 1)[0] for line in head.splitlines()[:-1] if line.strip()]
    if words and all(w.split(b"#")[0] in _OBJ_KEYWORDS or w.startswith(b"#") for w in words):
        return "OBJ"
    return None


def check_stl(path: Path, shown: Path) -> str:
    """"binary" or "ASCII" after checking the STL's size or structure."""
    size = path.stat().st_size
    with open(path, "rb") as handle:
        head = handle.read(84)
    if size >= 84:
        count = struct.unpack("<I", head[80:84])[0]
        if 84 + 50 * count == size:
            if count == 0:
                raise MeshReadError(shown, "the binary STL holds no triangles")
            return "binary"
    if head.lstrip()[:5].lower() == b"solid":
        require_fits(shown, size, "the ASCII STL text")
        text = path.read_bytes().lower()
        if b"\0" in text:
            raise MeshReadError(shown, "the file starts like an ASCII STL ('solid') but holds binary data, and its "
                                       "size does not match a binary STL either")
        facets, ends, vertices = text.count(b"facet normal"), text.count(b"endfacet"), len(re.findall(rb"\bvertex\b", text))
        if b"endsolid" not in text:
            raise MeshReadError(shown, "the ASCII STL has no 'endsolid' line (the file is truncated)",
                                "Re-export or re-copy it")
        if facets == 0:
            raise MeshReadError(shown, "the ASCII STL holds no facets")
        if facets != ends or vertices != 3 * facets:
            raise MeshReadError(shown, f"the ASCII STL is damaged: {facets} facets, {ends} 'endfacet' lines and "
                                       f"{vertices} vertices (3 per facet expected)")
        return "ASCII"
    if size < 84:
        raise MeshReadError(shown, f"the file has {size} bytes, too few for an STL (a binary STL has an 84-byte "
                                   "header)")
    count = struct.unpack("<I", head[80:84])[0]
    expected = 84 + 50 * count
    state = "truncated" if size < expected else f"{size - expected} bytes longer"
    raise MeshReadError(shown, f"the binary STL header declares {count} triangles ({expected} bytes) but the file has "
                               f"{size} bytes ({state})", "Re-export or re-copy it")


def check_obj(path: Path, shown: Path) -> None:
    """Check that every face index of an OBJ names an existing vertex."""
    require_fits(shown, path.stat().st_size * 4, "the OBJ text")
    vertices = 0
    faces = 0
    with open(path, "rb") as handle:
        for number, line in enumerate(handle, start=1):
            if line.startswith(b"v ") or line.startswith(b"v\t"):
                vertices += 1
            elif line.startswith(b"f ") or line.startswith(b"f\t"):
                faces += 1
                tokens = line.split(b"#")[0].split()[1:]
                if len(tokens) < 3:
                    raise MeshReadError(shown, f"line {number}: a face needs at least 3 vertices")
                for token in tokens:
                    try:
                        index = int(token.split(b"/")[0])
                    except ValueError as exc:
                        raise MeshReadError(shown, f"line {number}: '{token.decode('latin-1')[:20]}' is not a vertex "
                                                   "index") from exc
                    absolute = index if index > 0 else vertices + index + 1
                    if index == 0 or not 1 <= absolute <= vertices:
                        raise MeshReadError(shown, f"line {number}: face index {index} names no vertex (only "
                                                   f"{vertices} defined so far)", "The file is damaged")
            elif b"\0" in line:
                raise MeshReadError(shown, f"line {number} holds binary data; this is not an OBJ text file")
    if vertices == 0:
        raise MeshReadError(shown, "the OBJ file defines no vertices ('v' lines)")
    if faces == 0:
        raise MeshReadError(shown, "the OBJ file defines no faces ('f' lines)")


def _ply_header(path: Path, shown: Path):
    with open(path, "rb") as handle:
        lines = []
        while True:
            line = handle.readline(4096)
            if not line:
                raise MeshReadError(shown, "the PLY header has no 'end_header' line (the file is truncated)")
            lines.append(line.strip().decode("latin-1"))
            if lines[-1] == "end_header":
                return lines, handle.tell()
            if len(lines) > 10000:
                raise MeshReadError(shown, "the PLY header is too long (damaged)")


def check_ply(path: Path, shown: Path) -> None:
    """Check that a PLY body holds exactly the rows its header declares."""
    lines, offset = _ply_header(path, shown)
    fmt = None
    elements: list[list] = []  # [name, count, [(name, type, list count type or None)]]
    for line in lines[1:-1]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                elements.append([words[1], int(words[2]), []])
            elif words[0] == "property" and words[1] == "list":
                elements[-1][2].append((words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]]))
            elif words[0] == "property":
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]], None))
        except (IndexError, KeyError, ValueError) as exc:
            raise MeshReadError(shown, f"the PLY header line '{line[:60]}' is invalid") from exc
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise MeshReadError(shown, f"unknown PLY format '{fmt}'")
    names = {e[0]: e for e in elements}
    if "vertex" not in names or not {"x", "y", "z"} <= {p[0] for p in names["vertex"][2]}:
        raise MeshReadError(shown, "the PLY file has no vertex element with x, y, z")
    if any(e[1] < 0 for e in elements):
        raise MeshReadError(shown, "the PLY header declares a negative element count")
    if names["vertex"][1] == 0:
        raise MeshReadError(shown, "the PLY file has no vertices")
    if "face" not in names or names["face"][1] == 0:
        raise MeshReadError(shown, "the PLY file has no faces")
    require_fits(shown, sum(e[1] for e in elements) * 64, "the PLY elements")
    if fmt == "ascii":
        _check_ply_ascii(path, shown, offset, elements)
    else:
        _check_ply_binary(path, shown, offset, elements, "<" if fmt == "binary_little_endian" else ">")


def _check_ply_ascii(path: Path, shown: Path, offset: int, elements) -> None:
    with open(path, "rb") as handle:
        handle.seek(offset)
        rows = (line.split() for line in handle)
        rows = (row for row in rows if row)
        for name, count, properties in elements:
            for index in range(count):
                row = next(rows, None)
                if row is None:
                    raise MeshReadError(shown, f"the PLY body ends in element '{name}' row {index + 1} of {count} "
                                               "(truncated)", "Re-export or re-copy it")
                needed = 0
                for _, _, list_type in properties:
                    if list_type is None:
                        needed += 1
                    else:
                        try:
                            needed += 1 + int(row[needed])
                        except (IndexError, ValueError) as exc:
                            raise MeshReadError(shown, f"element '{name}' row {index + 1} has an invalid list "
                                                       "length") from exc
                if len(row) != needed:
                    raise MeshReadError(shown, f"element '{name}' row {index + 1} has {len(row)} values where "
                                               f"{needed} are expected")
        if next(rows, None) is not None:
            raise MeshReadError(shown, "the PLY body holds more rows than the header declares")


def _check_ply_binary(path: Path, shown: Path, offset: int, elements, order: str) -> None:
    size = path.stat().st_size
    position = offset
    with open(path, "rb") as handle:
        for name, count, properties in elements:
            if all(p[2] is None for p in properties):
                position += count * sum(np.dtype(p[1]).itemsize for p in properties)
                continue
            position = _walk_list_rows(handle, shown, position, size, name, count, properties, order)
    if position != size:
        state = "truncated" if position > size else f"{size - position} bytes longer than the header declares"
        raise MeshReadError(shown, f"the binary PLY body needs {position - offset} bytes but the file holds "
                                   f"{size - offset} ({state})", "Re-export or re-copy it")


def _walk_list_rows(handle, shown, position, size, name, count, properties, order) -> int:
    """Walk the rows of an element with list properties; fast when every list has the same length."""
    layout = [(np.dtype(p[1]).newbyteorder(order), None if p[2] is None else np.dtype(p[2]).newbyteorder(order))
              for p in properties]
    if len(layout) == 1 and layout[0][1] is not None and count:
        item, counter = layout[0]
        handle.seek(position)
        first = handle.read(counter.itemsize)
        if len(first) == counter.itemsize:
            length = int(np.frombuffer(first, counter)[0])
            stride = counter.itemsize + length * item.itemsize
            if 0 < length and position + stride * count <= size:
                handle.seek(position)
                block = np.frombuffer(handle.read(stride * count), np.uint8).reshape(count, stride)
                lengths = block[:, :counter.itemsize].copy().view(counter).ravel()
                if np.all(lengths == length):
                    return position + stride * count
    for _ in range(count):
        for item, counter in layout:
            if counter is None:
                position += item.itemsize
                continue
            handle.seek(position)
            raw = handle.read(counter.itemsize)
            if len(raw) < counter.itemsize:
                return size + 1
            length = int(np.frombuffer(raw, counter)[0])
            if length < 0:
                raise MeshReadError(shown, f"element '{name}' has a negative list length")
            position += counter.itemsize + length * item.itemsize
        if position > size:
            return position
    return position


def read_off(path: Path, shown: Path):
    """Points ``(n, 3)``, polygon offsets and connectivity of an OFF file (Geomview's Object File Format).

    The keyword (``OFF``, ``COFF``, ``NOFF``, ...) may carry the counts on the same line; vertex lines may hold
    colours or normals after x y z; face lines hold ``k`` then ``k`` indices (0-based), optionally a colour.
    """
    require_fits(shown, path.stat().st_size * 8, "the OFF text")
    text = path.read_bytes()
    if b"\0" in text:
        raise MeshReadError(shown, "the file holds binary data; binary OFF is not supported")
    lines = [line.split(b"#")[0].split() for line in text.splitlines()]
    lines = [line for line in lines if line]
    if not lines or not re.fullmatch(rb"[A-Z]*OFF", lines[0][0]):
        raise MeshReadError(shown, "not an OFF file (it must start with the keyword OFF)")
    counts = lines[0][1:] or (lines[1] if len(lines) > 1 else [])
    body = lines[1:] if lines[0][1:] else lines[2:]
    try:
        vertices, faces = int(counts[0]), int(counts[1])
    except (IndexError, ValueError) as exc:
        raise MeshReadError(shown, "the OFF counts line must give the numbers of vertices and faces") from exc
    if vertices <= 0 or faces <= 0:
        raise MeshReadError(shown, f"the OFF file declares {vertices} vertices and {faces} faces")
    if len(body) < vertices + faces:
        raise MeshReadError(shown, f"the OFF file declares {vertices} vertices and {faces} faces but holds "
                                   f"{len(body)} data lines (truncated)", "Re-export or re-copy it")
    if len(body) > vertices + faces:
        raise MeshReadError(shown, f"the OFF file holds {len(body) - vertices - faces} more data lines than it "
                                   "declares")
    try:
        points = np.array([[float(v) for v in line[:3]] for line in body[:vertices]], dtype=np.float64)
    except ValueError as exc:
        raise MeshReadError(shown, "an OFF vertex line holds something that is not a number") from exc
    if points.shape != (vertices, 3):
        raise MeshReadError(shown, "an OFF vertex line has fewer than 3 coordinates")
    offsets = [0]
    connectivity: list[int] = []
    for number, line in enumerate(body[vertices:], start=1):
        try:
            k = int(line[0])
            indices = [int(v) for v in line[1:1 + k]]
        except ValueError as exc:
            raise MeshReadError(shown, f"OFF face {number} holds something that is not an index") from exc
        if k < 3 or len(indices) != k:
            raise MeshReadError(shown, f"OFF face {number} declares {k} vertices but lists {len(indices)}")
        if min(indices) < 0 or max(indices) >= vertices:
            raise MeshReadError(shown, f"OFF face {number} names vertex {max(indices) if max(indices) >= vertices else min(indices)}"
                                       f" of {vertices}", "The file is damaged")
        connectivity.extend(indices)
        offsets.append(len(connectivity))
    return points, np.asarray(offsets, dtype=np.int64), np.asarray(connectivity, dtype=np.int64)
