"""Declared-size lies and the special values that broke readers before, per base file.

:func:`special_variants` returns ``(name, edit, must_fail)`` triples; ``edit(base)`` changes the copy in place.
Names starting with ``lie`` declare more or less data than the file holds; the others are special values.
"""

from __future__ import annotations

import gzip
import os
import struct
from pathlib import Path



def _replace(path: Path, old: bytes, new: bytes) -> None:
    data = path.read_bytes()
    if old not in data:
        raise ValueError(f"{old!r} not in {path}")
    path.write_bytes(data.replace(old, new, 1))


def _text(old: str, new: str, file: str | None = None):
    def edit(base):
        _replace(base.folder / (file or base.load), old.encode(), new.encode())
    return edit


def _struct(offset: int, fmt: str, *values, file: str | None = None, gz: bool = False):
    def edit(base):
        path = base.folder / (file or base.load)
        data = bytearray(gzip.decompress(path.read_bytes()) if gz else path.read_bytes())
        struct.pack_into(fmt, data, offset, *values)
        path.write_bytes(gzip.compress(bytes(data)) if gz else bytes(data))
    return edit


def _data_file(kind: str, header: str, old_name: str):
    """Point a detached header at a FIFO, /dev/zero or nothing."""
    def edit(base):
        if kind == "fifo":
            os.mkfifo(base.folder / "pipe.raw")
            name = "pipe.raw"
        elif kind == "zero":
            name = "/dev/zero"
        else:
            name = "missing.raw"
        _replace(base.folder / header, old_name.encode(), name.encode())
    return edit


def _nifti(base) -> list:
    gz = base.name == "nifti-gz"
    if base.name == "nifti2":
        return [
            ("dims-2^40", _struct(16, "<8q", 3, 2 ** 40, 1, 1, 1, 1, 1, 1), True),
            ("dims-negative", _struct(16, "<8q", 3, -18, 20, 6, 1, 1, 1, 1), True),
            ("vox-offset-0", _struct(168, "<q", 0), True),
            ("datatype-999", _struct(12, "<h", 999), True),
            ("lie-4d", _struct(16, "<8q", 4, 18, 20, 6, 7, 1, 1, 1), True),
        ]
    edits = [
        ("dims-32767^3", _struct(40, "<8h", 3, 32767, 32767, 32767, 1, 1, 1, 1, gz=gz), True),
        ("dims-negative", _struct(40, "<8h", 3, -18, 20, 6, 1, 1, 1, 1, gz=gz), True),
        ("dim0-zero", _struct(40, "<h", 0, gz=gz), True),
        ("dim0-nine", _struct(40, "<h", 9, gz=gz), True),
        ("datatype-999", _struct(70, "<h", 999, gz=gz), True),
        ("datatype-rgb", _struct(70, "<hh", 128, 24, gz=gz), True),
        ("vox-offset-0", _struct(108, "<f", 0.0, gz=gz), True),
        ("vox-offset-huge", _struct(108, "<f", 1e12, gz=gz), True),
        ("vox-offset-nan", _struct(108, "<f", float("nan"), gz=gz), True),
        ("pixdim-nan", _struct(80, "<3f", float("nan"), 1, 1, gz=gz), False),  # unused: the sform places voxels
        ("pixdim-zero", _struct(76, "<4f", 1, 0, 0, 0, gz=gz), False),  # sform still places the voxels
        ("sizeof-hdr-0", _struct(0, "<i", 0, gz=gz), True),
        ("lie-bigger", _struct(40, "<4h", 3, 19, 20, 6, gz=gz), True),
        ("lie-smaller", _struct(40, "<4h", 3, 17, 20, 6, gz=gz), True),
        ("lie-4d", _struct(40, "<5h", 4, 18, 20, 6, 3, gz=gz), True),
        ("lie-float64", _struct(70, "<hh", 64, 64, gz=gz), True),
    ]
    if gz:
        def crc(base):
            path = base.folder / base.load
            data = bytearray(path.read_bytes())
            data[-7] ^= 0x10
            path.write_bytes(bytes(data))

        def trailing(base):
            path = base.folder / base.load
            path.write_bytes(path.read_bytes() + b"garbage after the stream")

        def more_data(base):
            path = base.folder / base.load
            path.write_bytes(gzip.compress(gzip.decompress(path.read_bytes()) + bytes(1 << 20)))

        def bomb(base):
            path = base.folder / base.load
            data = bytearray(gzip.decompress(path.read_bytes())[:352])
            struct.pack_into("<8h", data, 40, 3, 2048, 2048, 2048, 1, 1, 1, 1)  # 16 GiB of int16
            with gzip.open(path, "wb", compresslevel=1) as stream:
                stream.write(bytes(data))
                for _ in range(64):
                    stream.write(bytes(1 << 20))
        edits += [("crc-error", crc, True), ("trailing-garbage", trailing, True), ("lie-more-data", more_data, True),
                  ("bomb-16GiB", bomb, True)]
    return edits


def _nrrd(base) -> list:
    header = "v.nhdr" if base.name.startswith("nhdr") else "v.nrrd"
    edits = [
        ("sizes-32767^3", _text("sizes: 18 20 6", "sizes: 32767 32767 32767", header), True),
        ("sizes-negative", _text("sizes: 18 20 6", "sizes: -18 20 6", header), True),
        ("sizes-2^40", _text("sizes: 18 20 6", "sizes: 1099511627776 1 6", header), True),
        ("type-999", _text("type: short", "type: 999", header), True),
        ("endian-middle", _text("endian: little", "endian: middle", header), True),
        ("byte-skip-5", _text("endian: little", "endian: little\nbyte skip: -5", header), True),
        ("line-skip-1e9", _text("endian: little", "endian: little\nline skip: 1000000000", header), True),
        ("origin-letters", _text("space origin: (", "space origin: (a,b,", header), True),
        ("directions-short", _text("(0,1.25,0)", "(0,1.25)", header), True),
        ("dimension-2", _text("dimension: 3", "dimension: 2", header), True),
        ("lie-bigger", _text("sizes: 18 20 6", "sizes: 18 20 7", header), True),
        ("lie-smaller", _text("sizes: 18 20 6", "sizes: 18 20 5", header), True),
    ]
    if base.name.startswith("nhdr"):
        data = "v.raw.gz" if base.name == "nhdr-gz" else "v.raw"
        edits += [("data-fifo", _data_file("fifo", header, data), True),
                  ("data-dev-zero", _data_file("zero", header, data), True),
                  ("data-missing", _data_file("missing", header, data), True),
                  ("data-list", _text(f"data file: {data}", "data file: LIST", header), True),
                  ("data-pattern", _text(f"data file: {data}", "data file: v%03d.raw 1 6 1", header), True)]
    return edits


def _metaimage(base) -> list:
    header = "v.mhd" if base.name.startswith("mhd") else "v.mha"
    edits = [
        ("dimsize-1e5^3", _text("DimSize = 18 20 6", "DimSize = 100000 100000 100000", header), True),
        ("dimsize-negative", _text("DimSize = 18 20 6", "DimSize = -18 20 6", header), True),
        ("dimsize-two", _text("DimSize = 18 20 6", "DimSize = 18 20", header), True),
        ("ndims-4", _text("NDims = 3", "NDims = 4", header), True),
        ("type-unknown", _text("MET_SHORT", "MET_QUATERNION", header), True),
        ("lie-double", _text("MET_SHORT", "MET_DOUBLE", header), True),
        ("channels-3", _text("NDims = 3", "NDims = 3\nElementNumberOfChannels = 3", header), True),
        ("spacing-zero", _text("ElementSpacing = 1.5 1.25 3", "ElementSpacing = 0 0 0", header), True),
        ("matrix-zero", _text("TransformMatrix = 1 0 0 0 1 0 0 0 1", "TransformMatrix = 0 0 0 0 0 0 0 0 0", header), True),
        ("lie-bigger", _text("DimSize = 18 20 6", "DimSize = 18 20 7", header), True),
        ("lie-smaller", _text("DimSize = 18 20 6", "DimSize = 18 20 5", header), True),
    ]
    if base.name in ("mha-zlib", "mhd-zraw", "mhd-header"):
        edits += [("compressed-size-1e12", _compressed_size("1000000000000", header), True),
                  ("compressed-size-10", _compressed_size("10", header), True)]
    if base.name.startswith("mhd"):
        data = "v.raw" if base.name == "mhd-raw" else "v.zraw"
        edits += [("data-fifo", _data_file("fifo", header, data), True),
                  ("data-dev-zero", _data_file("zero", header, data), True),
                  ("data-missing", _data_file("missing", header, data), True),
                  ("data-list", _text(f"ElementDataFile = {data}", "ElementDataFile = LIST", header), True),
                  ("header-size-huge", _text("ElementType", "HeaderSize = 1000000000000\nElementType", header), True)]
    return edits


def _compressed_size(value: str, header: str):
    def edit(base):
        path = base.folder / header
        lines = path.read_bytes().split(b"\n")
        lines = [b"CompressedDataSize = " + value.encode() if line.startswith(b"CompressedDataSize") else line
                 for line in lines]
        path.write_bytes(b"\n".join(lines))
    return edit


def _vti(base) -> list:
    edits = [
        ("extent-1e5^3", _both_extents("0 99999 0 99999 0 99999"), True),
        ("extent-inverted", _both_extents("0 17 0 19 5 0"), True),
        ("piece-outside", _text('<Piece Extent="0 17 0 19 0 5"', '<Piece Extent="0 17 0 19 0 9"'), True),
        ("components-3", _text('Name="scalars"', 'Name="scalars" NumberOfComponents="3"'), True),
        ("type-float64", _text('type="Int16"', 'type="Float64"'), base.name != "vti-ascii"),  # ASCII: same values
        ("type-unknown", _text('type="Int16"', 'type="Int99"'), True),
        ("spacing-nan", _text('Spacing="1.5 1.25 3"', 'Spacing="nan 1.25 3"'), True),
        ("compressor-unknown", _text("vtkZLibDataCompressor", "vtkFooDataCompressor"), True),
        ("header-uint64", _text('header_type="UInt32"', 'header_type="UInt64"'), base.name != "vti-ascii"),
        ("polydata", _text('type="ImageData"', 'type="PolyData"'), True),
        ("lie-bigger", _both_extents("0 17 0 19 0 6"), True),
        ("lie-smaller", _both_extents("0 17 0 19 0 4"), True),
    ]
    if base.name in ("vti-raw", "vti-base64"):
        edits.append(("offset-huge", _offset_huge, True))
    return edits


def _both_extents(extent: str):
    def edit(base):
        path = base.folder / base.load
        data = path.read_bytes()
        for key in (b'WholeExtent="0 17 0 19 0 5"', b'<Piece Extent="0 17 0 19 0 5"'):
            data = data.replace(key, key.split(b'"')[0] + b'"' + extent.encode() + b'"', 1)
        path.write_bytes(data)
    return edit


def _offset_huge(base):
    path = base.folder / base.load
    data = path.read_bytes()
    at = data.index(b'offset="', data.index(b'Name="scalars"'))
    end = data.index(b'"', at + 8)
    path.write_bytes(data[:at + 8] + b"99999999999" + data[end:])


def _legacy(base) -> list:
    return [
        ("dims-1e5^3", _text("DIMENSIONS 18 20 6", "DIMENSIONS 100000 100000 100000"), True),
        ("dims-1e5^3-consistent", _legacy_consistent, True),
        ("dims-negative", _text("DIMENSIONS 18 20 6", "DIMENSIONS -18 20 6"), True),
        ("type-unknown", _text("SCALARS scalars short", "SCALARS scalars quaternion"), True),
        ("spacing-zero", _text("SPACING 1.5 1.25 3", "SPACING 0 0 0"), True),
        ("polydata", _text("DATASET STRUCTURED_POINTS", "DATASET POLYDATA"), True),
        ("lie-bigger", _legacy_dims(7), True),
        ("lie-smaller", _legacy_dims(5), True),
    ]


def _legacy_dims(nz: int):
    def edit(base):
        _text("DIMENSIONS 18 20 6", f"DIMENSIONS 18 20 {nz}")(base)
        _text("POINT_DATA 2160", f"POINT_DATA {18 * 20 * nz}")(base)
    return edit


def _legacy_consistent(base):
    _text("DIMENSIONS 18 20 6", "DIMENSIONS 100000 100000 100000")(base)
    _text("POINT_DATA 2160", "POINT_DATA 1000000000000000")(base)


def _dicom(base) -> list:
    from ..dicom_helpers import patch_element

    def element(keyword: str, value: bytes, every: bool = False):
        import pydicom

        tag = pydicom.datadict.tag_for_keyword(keyword)

        def edit(target):
            files = sorted(target.folder.iterdir()) if every else [target.damaged]
            for path in files:
                patch_element(path, tag, value)
        return edit

    def us(keyword: str, value: int, every: bool = False):
        return element(keyword, struct.pack("<H", value), every)

    def frames(value: str):
        def edit(target):
            import warnings

            import pydicom

            from ..dicom_helpers import lenient_pydicom

            with lenient_pydicom(), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ds = pydicom.dcmread(target.damaged)
                ds.add_new(0x00280008, "IS", "1")
                ds.save_as(target.damaged)
            patch_element(target.damaged, 0x00280008, value.encode())
        return edit

    return [
        ("rows-65535", us("Rows", 65535), True),
        ("rows-0", us("Rows", 0), True),
        ("bits-13", us("BitsAllocated", 13), True),
        ("samples-3", us("SamplesPerPixel", 3), True),
        ("frames-1A", frames("1A"), True),
        ("frames-1e6", frames("1000000"), True),
        ("spacing-zero-all", element("PixelSpacing", b"0\\0", every=True), True),
        ("position-nan", element("ImagePositionPatient", b"nan\\0\\0"), True),
        ("orientation-zero-all", element("ImageOrientationPatient", b"0\\0\\0\\0\\0\\0", every=True), True),
        ("slope-x", element("RescaleSlope", b"x"), True),
        ("slope-0", element("RescaleSlope", b"0"), True),
        ("intercept-two", element("RescaleIntercept", b"1\\2"), True),
        ("lie-rows", us("Rows", 21), True),
    ]


def special_variants(base) -> list:
    """The lies and special values that apply to ``base``."""
    if base.fmt == "NIfTI":
        return _nifti(base)
    if base.fmt == "NRRD":
        return _nrrd(base)
    if base.fmt == "MetaImage":
        return _metaimage(base)
    if base.fmt == "VTI":
        return _vti(base)
    if base.fmt == "VTK legacy":
        return _legacy(base)
    return _dicom(base)

