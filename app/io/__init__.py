"""Reading and writing volumes: one entry point, :func:`load_volume`, dispatching on what the path is.

============================  ==========================================================
path                          reader
============================  ==========================================================
folder                        DICOM series (largest stack, or ``series_uid``)
``*.dcm`` / DICOM file        multi-frame DICOM file, or the series of its folder
``*.nii``, ``*.nii.gz``       NIfTI (nibabel), RAS converted to LPS
``*.hdr``, ``*.img``          Analyze 7.5 (nibabel)
``*.mnc``                     MINC 1 (nibabel; MINC 2 needs h5py)
``*.nrrd``, ``*.nhdr``        NRRD
``*.mha``, ``*.mhd``          MetaImage (VTK reader, ITK geometry)
``*.vti``, ``*.vtk``          VTK image (XML or legacy)
anything with ``raw=``        raw voxels with an explicit :class:`RawLayout`
============================  ==========================================================
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..volume import Volume, right_handed
from .dicom import is_dicom_file, list_series, read_dicom_series, read_multiframe, write_dicom_series
from .errors import (
    CorruptFileError,
    DicomSeriesError,
    FileExistsRefusal,
    MissingDecoderError,
    UnsupportedFormatError,
    VolumeReadError,
    VolumeWriteError,
)
from .formats import (
    RawLayout,
    read_metaimage,
    read_nifti,
    read_nrrd,
    read_raw,
    read_vtk_image,
    write_metaimage,
    write_nifti,
    write_nrrd,
    write_vti,
)

__all__ = [
    "load_volume", "save_volume", "volume_format", "list_series", "write_dicom_series", "RawLayout",
    "VolumeReadError", "UnsupportedFormatError", "CorruptFileError", "DicomSeriesError", "MissingDecoderError",
    "VolumeWriteError", "FileExistsRefusal", "READABLE_SUFFIXES", "WRITABLE_SUFFIXES",
]

READABLE_SUFFIXES = (".dcm", ".nii", ".nii.gz", ".hdr", ".img", ".mnc", ".nrrd", ".nhdr", ".mha", ".mhd", ".vti", ".vtk")
WRITABLE_SUFFIXES = (".nii", ".nii.gz", ".nrrd", ".mha", ".mhd", ".vti")


def _suffix(path: Path) -> str:
    name = path.name.lower()
    if name.endswith(".nii.gz"):
        return ".nii.gz"
    if name.endswith(".gz"):
        return "".join(path.suffixes[-2:]).lower()
    return path.suffix.lower()


def volume_format(path) -> str:
    """A short name of the format ``load_volume`` would use for ``path`` (raises for unknown paths)."""
    path = Path(path)
    if path.is_dir():
        return "DICOM series"
    suffix = _suffix(path)
    formats = {
        ".nii": "NIfTI", ".nii.gz": "NIfTI", ".hdr": "Analyze", ".img": "Analyze", ".mnc": "MINC", ".nrrd": "NRRD", ".nhdr": "NRRD",
        ".mha": "MetaImage", ".mhd": "MetaImage", ".vti": "VTK XML image", ".vtk": "VTK legacy", ".dcm": "DICOM",
    }
    if suffix in formats:
        return formats[suffix]
    if is_dicom_file(path):
        return "DICOM"
    raise UnsupportedFormatError(
        path, f"unknown volume format '{suffix or path.name}'",
        "Voxelscope reads DICOM folders and files, NIfTI (.nii, .nii.gz), Analyze (.hdr/.img), MINC (.mnc), "
        "NRRD (.nrrd, .nhdr), "
        "MetaImage (.mha, .mhd), VTK images (.vti, .vtk), and raw files with their layout given",
    )


def load_volume(
    path,
    *,
    series_uid: str | None = None,
    raw: RawLayout | None = None,
    irregular: str = "resample",
    progress: Callable[[float], None] | None = None,
) -> Volume:
    """Read the volume at ``path`` (file or DICOM folder) into a :class:`Volume` in LPS millimetres.

    Raises a :class:`VolumeReadError` subclass whose message names the file, the problem and what to do.
    """
    path = Path(path).expanduser()
    if not path.exists():
        raise VolumeReadError(path, "no such file or folder", "Check the path")
    if raw is not None:
        volume = read_raw(path, raw)
    elif path.is_dir():
        volume = read_dicom_series(path, series_uid=series_uid, irregular=irregular, progress=progress)
    else:
        fmt = volume_format(path)
        if path.stat().st_size == 0:
            raise CorruptFileError(path, "the file is empty (0 bytes)", "Re-export or re-copy it")
        if fmt == "DICOM":
            volume = _read_dicom_file(path, series_uid, irregular, progress)
        elif fmt in ("NIfTI", "Analyze", "MINC"):
            volume = read_nifti(path)
        elif fmt == "NRRD":
            volume = read_nrrd(path)
        elif fmt == "MetaImage":
            volume = read_metaimage(path)
        else:
            volume = read_vtk_image(path)
    if min(volume.dimensions) < 2:
        raise UnsupportedFormatError(
            path, f"the image is {'x'.join(map(str, volume.dimensions))} voxels; a volume needs at least 2 on every axis"
        )
    volume.metadata.setdefault("source_path", str(path))
    return right_handed(volume)


def _read_dicom_file(path: Path, series_uid, irregular, progress) -> Volume:
    """A single DICOM file: a multi-frame volume, or one slice of a series (then read its folder's series)."""
    from .dicom import read_header

    try:
        header = read_header(path)
    except Exception as exc:  # pydicom raises many types for damaged files
        raise CorruptFileError(path, f"not a readable DICOM file ({type(exc).__name__}: {exc})") from exc
    if int(header.get("NumberOfFrames", 1) or 1) > 1:
        return read_multiframe(path)
    uid = series_uid or str(header.get("SeriesInstanceUID", "") or "") or None
    return read_dicom_series(path.parent, series_uid=uid, irregular=irregular, progress=progress)


def save_volume(volume: Volume, path, *, overwrite: bool = False) -> Path:
    """Write ``volume`` by the extension of ``path`` (NIfTI, NRRD, MetaImage or VTI), atomically."""
    path = Path(path).expanduser()
    suffix = _suffix(path)
    if suffix in (".nii", ".nii.gz"):
        return write_nifti(volume, path, overwrite=overwrite)
    if suffix == ".nrrd":
        return write_nrrd(volume, path, overwrite=overwrite)
    if suffix in (".mha", ".mhd"):
        return write_metaimage(volume, path, overwrite=overwrite)
    if suffix == ".vti":
        return write_vti(volume, path, overwrite=overwrite)
    raise VolumeWriteError(f"{path}: cannot write '{suffix}'; use one of {', '.join(WRITABLE_SUFFIXES)}")
