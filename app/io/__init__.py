"""Reading and writing volumes and meshes: one entry point each, :func:`load_volume` and :func:`load_mesh`.

============================  ==========================================================
path                          reader
============================  ==========================================================
folder                        DICOM series (largest stack, or ``series_uid``)
``*.dcm`` / DICOM file        multi-frame or MOSAIC DICOM file, or the series of its folder
``*.nii``, ``*.nii.gz``       NIfTI (nibabel headers), RAS converted to LPS
``*.hdr``, ``*.img``          Analyze 7.5 or NIfTI pair (nibabel)
``*.mnc``                     MINC 1 and 2 (nibabel; MINC 2 through h5py)
``*.nrrd``, ``*.nhdr``        NRRD (pynrrd headers)
``*.mha``, ``*.mhd``          MetaImage (header checked here, pixels by VTK, ITK geometry)
``*.vti``, ``*.vtk``          VTK image (XML or legacy; header checked before VTK reads it)
anything with ``raw=``        raw voxels with an explicit :class:`RawLayout`
``*.zarr`` folder             Zarr v2/v3, OME-Zarr pyramids (:mod:`app.io.zarr`; lazy: :func:`open_zarr`)
``*.stl .obj .ply .vtp .off``  surface meshes, optionally gzipped: :func:`load_mesh` (:mod:`app.io.meshes`)
============================  ==========================================================

The contract of every reader: a damaged, truncated or hostile file gives a :class:`VolumeReadError` (a
:class:`MeshReadError` for meshes) whose message is one line naming the file, what is wrong and what to do;
never a traceback, a crash, a hang or a runaway allocation.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..volume import Volume, right_handed
from .dicom import is_dicom_file, list_series, read_dicom_file, read_dicom_series, read_multiframe, write_dicom_series
from .errors import (
    CorruptFileError,
    DicomSeriesError,
    FileExistsRefusal,
    MeshReadError,
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
from .meshes import MESH_SUFFIXES_READ, Mesh, describe_mesh, is_mesh_path, load_mesh
from .safety import one_line, require_regular_file
from .zarr import ChunkedVolume, is_zarr_path, open_zarr, read_zarr, save_zarr

__all__ = [
    "load_volume", "save_volume", "volume_format", "list_series", "write_dicom_series", "RawLayout",
    "VolumeReadError", "UnsupportedFormatError", "CorruptFileError", "DicomSeriesError", "MissingDecoderError",
    "VolumeWriteError", "FileExistsRefusal", "READABLE_SUFFIXES", "WRITABLE_SUFFIXES",
    "ChunkedVolume", "open_zarr", "is_zarr_path",
    "Mesh", "MeshReadError", "MESH_SUFFIXES_READ", "describe_mesh", "is_mesh_path", "load_mesh", "read_multiframe",
]

READABLE_SUFFIXES = (".zarr", ".dcm", ".nii", ".nii.gz", ".hdr", ".img", ".mnc", ".nrrd", ".nhdr", ".mha", ".mhd", ".vti", ".vtk")
WRITABLE_SUFFIXES = (".zarr", ".nii", ".nii.gz", ".nrrd", ".mha", ".mhd", ".vti")


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
    if is_zarr_path(path):
        return "Zarr"
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
    if is_mesh_path(path):
        raise UnsupportedFormatError(path, "this is a surface mesh, not a volume",
                                     "Open it as a mesh (load_mesh; 'voxelscope info' reads meshes too)")
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
    allow_gaps: bool = False,
    volume_index: int | None = None,
    progress: Callable[[float], None] | None = None,
) -> Volume:
    """Read the volume at ``path`` (file or DICOM folder) into a :class:`Volume` in LPS millimetres.

    Parameters
    ----------
    series_uid : str, optional
        DICOM SeriesInstanceUID to load (default: the largest stack). CLI: ``--series UID``.
    raw : RawLayout, optional
        Layout of a headerless raw file (dimensions, type, spacing, byte order, header size). CLI: ``--raw-*``.
    irregular : {"resample", "error"}
        DICOM slices missing or unevenly spaced: resample (default) or refuse. CLI: ``--strict-spacing``.
    allow_gaps : bool
        Interpolate across DICOM gaps of more than two missing slices (refused by default). CLI: ``--allow-gaps``.
    volume_index : int, optional
        Which volume of a DICOM series holding several (echoes, time points, MOSAIC files), from 0; default the
        first, with a warning listing the others. CLI: ``--volume N``.
    progress : callable, optional
        Called with a fraction in [0, 1] (DICOM folders).

    Raises a :class:`VolumeReadError` subclass whose one-line message names the file, the problem and what to do.
    ``ValueError`` is raised only for invalid arguments (a raw layout that makes no sense, an unknown
    ``irregular``).
    """
    path = Path(path).expanduser()
    if irregular not in ("resample", "error"):
        raise ValueError(f"irregular must be 'resample' or 'error', got {irregular!r}")
    if raw is not None:
        raw.checked_dtype()  # argument errors stay ValueError
    if not path.exists():
        raise VolumeReadError(path, "no such file or folder", "Check the path")
    try:
        volume = _read(path, series_uid, raw, irregular, allow_gaps, volume_index, progress)
    except VolumeReadError:
        raise
    except MemoryError as exc:
        raise VolumeReadError(path, "there is not enough memory to read it",
                              "Close other programs or use a machine with more memory") from exc
    except Exception as exc:
        if type(exc).__name__ == "OperationCancelled":
            raise
        # The last line of defence of the contract above: an exception no reader anticipated.
        error = CorruptFileError(path, f"the file could not be read ({type(exc).__name__}: {one_line(exc)[:200]})",
                                 "It may be damaged or in an unsupported variant of its format")
        error.unexpected = True
        raise error from exc
    if min(volume.dimensions) < 2:
        raise UnsupportedFormatError(
            path, f"the image is {'x'.join(map(str, volume.dimensions))} voxels; a volume needs at least 2 on every axis"
        )
    volume.metadata.setdefault("source_path", str(path))
    volume.metadata.setdefault("warnings", [])
    return right_handed(volume)


def _read(path: Path, series_uid, raw, irregular, allow_gaps, volume_index, progress) -> Volume:
    dicom = dict(series_uid=series_uid, irregular=irregular, allow_gaps=allow_gaps, volume_index=volume_index,
                 progress=progress)
    if raw is not None:
        return read_raw(path, raw)
    if is_zarr_path(path):  # level 0 in memory when it fits; open_zarr gives the lazy ChunkedVolume
        return read_zarr(path)
    if path.is_dir():
        return read_dicom_series(path, **dicom)
    fmt = volume_format(path)
    if require_regular_file(path).st_size == 0:  # FIFOs and devices are refused before anything opens them
        raise CorruptFileError(path, "the file is empty (0 bytes)", "Re-export or re-copy it")
    if fmt == "DICOM":
        return read_dicom_file(path, **dicom)
    if fmt in ("NIfTI", "Analyze", "MINC"):
        return read_nifti(path)
    if fmt == "NRRD":
        return read_nrrd(path)
    if fmt == "MetaImage":
        return read_metaimage(path)
    return read_vtk_image(path)


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
    if suffix == ".zarr":
        return save_zarr(volume, path, overwrite=overwrite)
    raise VolumeWriteError(f"{path}: cannot write '{suffix}'; use one of {', '.join(WRITABLE_SUFFIXES)}")

