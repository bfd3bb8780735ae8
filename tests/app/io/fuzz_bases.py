"""The intact files the fuzz generator damages: one small CT phantom written in every format and variant.

Each :class:`Base` knows its files, which one the variants damage, and where that file's header ends and its
payload (voxels) starts and ends, so a variant can tell header damage from payload damage.
"""

from __future__ import annotations

import gzip
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Base:
    name: str
    fmt: str
    folder: Path
    load: str  # relative path given to load_volume ("." for a DICOM folder)
    damage: str  # relative path of the file the variants damage
    header_end: int  # payload starts here in the damaged file (== size: header only)
    payload_stop: int  # payload ends here (0: cutting never removes payload, e.g. a detached header)
    checked: bool  # the payload has a checksum or structure a reader can verify (compressed data)
    files: list[Path] = field(default_factory=list)

    @property
    def load_path(self) -> Path:
        return self.folder if self.load == "." else self.folder / self.load

    @property
    def damaged(self) -> Path:
        return self.folder / self.damage

    def payload_start(self, file: Path) -> int:
        return self.header_end

    def payload_end(self, file: Path) -> int:
        return self.payload_stop

    def payload_checked(self, file: Path) -> bool:
        return self.checked

    def copy_to(self, folder: Path) -> "Base":
        shutil.copytree(self.folder, folder)
        copy = Base(self.name, self.fmt, folder, self.load, self.damage, self.header_end, self.payload_stop,
                    self.checked)
        copy.files = sorted(p for p in folder.rglob("*") if p.is_file())
        return copy


def phantom():
    from ..dicom_helpers import small_ct

    return small_ct(shape=(6, 20, 18))


def _base(name, fmt, folder, load, damage, header_end, payload_stop, checked) -> Base:
    base = Base(name, fmt, folder, load, damage, header_end, payload_stop, checked)
    base.files = sorted(p for p in folder.rglob("*") if p.is_file())
    return base


def _dicom(root: Path, volume) -> Base:
    from app.io import write_dicom_series

    folder = root / "dicom"
    paths = write_dicom_series(volume, folder, rescale_intercept=-1024)
    data = paths[2].read_bytes()
    pixel_value = data.rindex(b"\xe0\x7f\x10\x00") + 12  # (7FE0,0010) OW: tag, VR, reserved, 4-byte length
    return _base("dicom", "DICOM", folder, ".", paths[2].name, pixel_value, len(data), False)


def _nifti(root: Path, volume) -> list[Base]:
    import nibabel

    from app.io import save_volume

    bases = []
    for name, suffix, checked in (("nifti", ".nii", False), ("nifti-gz", ".nii.gz", True)):
        folder = root / name
        folder.mkdir()
        path = save_volume(volume, folder / f"v{suffix}")
        size = path.stat().st_size
        bases.append(_base(name, "NIfTI", folder, path.name, path.name, 10 if checked else 352, size, checked))
    folder = root / "nifti2"
    folder.mkdir()
    image = nibabel.Nifti2Image(np.asarray(volume.array).transpose(2, 1, 0), np.diag(list(volume.spacing) + [1.0]))
    nibabel.save(image, folder / "v2.nii")
    bases.append(_base("nifti2", "NIfTI", folder, "v2.nii", "v2.nii", 544, (folder / "v2.nii").stat().st_size, False))
    return bases


def _nrrd(root: Path, volume) -> list[Base]:
    from app.io import save_volume

    array = np.ascontiguousarray(volume.array, dtype="<i2")
    header = ("NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: 18 20 6\n"
              "space directions: (1.5,0,0) (0,1.25,0) (0,0,3)\nkinds: domain domain domain\nendian: little\n"
              "encoding: {encoding}\nspace origin: (-20,35,110)\n")
    bases = []
    folder = root / "nrrd-gzip"
    folder.mkdir()
    path = save_volume(volume, folder / "v.nrrd")
    data = path.read_bytes()
    bases.append(_base("nrrd-gzip", "NRRD", folder, "v.nrrd", "v.nrrd", data.index(b"\n\n") + 2, len(data), True))
    folder = root / "nrrd-raw"
    folder.mkdir()
    text = (header.format(encoding="raw") + "\n").encode()
    (folder / "v.nrrd").write_bytes(text + array.tobytes())
    bases.append(_base("nrrd-raw", "NRRD", folder, "v.nrrd", "v.nrrd", len(text), len(text) + array.nbytes, False))
    for name, encoding, data_name, payload, checked in (
            ("nhdr-raw", "raw", "v.raw", array.tobytes(), False),
            ("nhdr-gz", "gzip", "v.raw.gz", gzip.compress(array.tobytes()), True)):
        folder = root / name
        folder.mkdir()
        (folder / "v.nhdr").write_text(header.format(encoding=encoding) + f"data file: {data_name}\n")
        (folder / data_name).write_bytes(payload)
        bases.append(_base(name, "NRRD", folder, "v.nhdr", data_name, 0, len(payload), checked))
    folder = root / "nhdr-header"
    shutil.copytree(root / "nhdr-raw", folder)
    size = (folder / "v.nhdr").stat().st_size
    bases.append(_base("nhdr-header", "NRRD", folder, "v.nhdr", "v.nhdr", size, 0, False))
    return bases


def _metaimage(root: Path, volume) -> list[Base]:
    from app.io import save_volume

    bases = []
    folder = root / "mha-zlib"
    folder.mkdir()
    path = save_volume(volume, folder / "v.mha")
    data = path.read_bytes()
    start = data.index(b"ElementDataFile = LOCAL\n") + len(b"ElementDataFile = LOCAL\n")
    bases.append(_base("mha-zlib", "MetaImage", folder, "v.mha", "v.mha", start, len(data), True))
    folder = root / "mha-raw"
    folder.mkdir()
    text = data[:start].replace(b"CompressedData = True", b"CompressedData = False")
    text = b"\n".join(line for line in text.split(b"\n") if not line.startswith(b"CompressedDataSize"))
    raw = np.ascontiguousarray(volume.array, dtype="<i2").tobytes()
    (folder / "v.mha").write_bytes(text + raw)
    bases.append(_base("mha-raw", "MetaImage", folder, "v.mha", "v.mha", len(text), len(text) + len(raw), False))
    folder = root / "mhd-zraw"
    folder.mkdir()
    save_volume(volume, folder / "v.mhd")
    size = (folder / "v.zraw").stat().st_size
    bases.append(_base("mhd-zraw", "MetaImage", folder, "v.mhd", "v.zraw", 0, size, True))
    folder = root / "mhd-header"
    shutil.copytree(root / "mhd-zraw", folder)
    size = (folder / "v.mhd").stat().st_size
    bases.append(_base("mhd-header", "MetaImage", folder, "v.mhd", "v.mhd", size, 0, False))
    folder = root / "mhd-raw"
    folder.mkdir()
    header = (folder.parent / "mhd-zraw" / "v.mhd").read_text().replace("CompressedData = True", "CompressedData = False")
    header = "\n".join(line for line in header.splitlines() if not line.startswith("CompressedDataSize"))
    (folder / "v.mhd").write_text(header.replace("v.zraw", "v.raw") + "\n")
    (folder / "v.raw").write_bytes(raw)
    bases.append(_base("mhd-raw", "MetaImage", folder, "v.mhd", "v.raw", 0, len(raw), False))
    return bases


def _vti(root: Path, volume) -> list[Base]:
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    from app.io import save_volume

    bases = []
    folder = root / "vti-raw"
    folder.mkdir()
    path = save_volume(volume, folder / "v.vti")
    data = path.read_bytes()
    start = data.index(b"_", data.index(b"<AppendedData")) + 1
    bases.append(_base("vti-raw", "VTI", folder, "v.vti", "v.vti", start, len(data), True))
    for name, mode, encode, checked in (("vti-base64", "appended", True, True), ("vti-inline", "binary", False, True),
                                        ("vti-ascii", "ascii", False, False)):
        folder = root / name
        folder.mkdir()
        writer = vtkXMLImageDataWriter()
        writer.SetInputData(volume.to_vtk())
        writer.SetFileName(str(folder / "v.vti"))
        writer.SetCompressorTypeToZLib()
        {"appended": writer.SetDataModeToAppended, "binary": writer.SetDataModeToBinary,
         "ascii": writer.SetDataModeToAscii}[mode]()
        writer.SetEncodeAppendedData(encode)
        writer.Write()
        data = (folder / "v.vti").read_bytes()
        marker = b"_" if mode == "appended" else b'format="' + mode.encode() + b'"'
        anchor = data.index(b"<AppendedData") if mode == "appended" else 0
        start = data.index(b">", data.index(marker, anchor)) + 1 if mode != "appended" else data.index(b"_", anchor) + 1
        bases.append(_base(name, "VTI", folder, "v.vti", "v.vti", start, len(data), checked))
    return bases


def _legacy(root: Path, volume) -> list[Base]:
    from vtkmodules.vtkIOLegacy import vtkStructuredPointsWriter

    bases = []
    for name, binary in (("vtk-binary", True), ("vtk-ascii", False)):
        folder = root / name
        folder.mkdir()
        writer = vtkStructuredPointsWriter()
        writer.SetInputData(volume.to_vtk(local=True))
        writer.SetFileName(str(folder / "v.vtk"))
        if binary:
            writer.SetFileTypeToBinary()
        else:
            writer.SetFileTypeToASCII()
        writer.Write()
        data = (folder / "v.vtk").read_bytes()
        start = data.index(b"\n", data.index(b"LOOKUP_TABLE")) + 1
        if binary:
            stop = start + volume.array.size * volume.array.dtype.itemsize
        else:  # a cut inside the last number leaves as many numbers: no reader can tell, so it is not "damage"
            body = data.rstrip()
            stop = max(body.rfind(b" "), body.rfind(b"\n")) + 1
        bases.append(_base(name, "VTK legacy", folder, "v.vtk", "v.vtk", start, stop, False))
    return bases


def make_bases(root: Path) -> list[Base]:
    """Write every base file under ``root``."""
    root.mkdir(parents=True, exist_ok=True)
    volume = phantom()
    return [_dicom(root, volume), *_nifti(root, volume), *_nrrd(root, volume), *_metaimage(root, volume),
            *_vti(root, volume), *_legacy(root, volume)]
