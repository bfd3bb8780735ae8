"""NIfTI-1/2 (``.nii``, ``.nii.gz``), Analyze 7.5 and NIfTI pairs (``.hdr``/``.img``), MINC 1/2 (``.mnc``).

Headers are parsed by nibabel's header classes; everything they declare is checked here before a byte of voxel
data is allocated:

- ``sizeof_hdr`` and the magic say which header it is; ``dim[0]`` is 3 to 7 and every used ``dim`` is at least 1;
  the datatype code is one nibabel knows and a grey-value type (RGB and complex images are refused);
- ``vox_offset`` lies after the header of a single file, and the file (or, for ``.nii.gz``, the decompressed
  stream) holds exactly ``vox_offset`` plus the declared data: fewer bytes is truncation, more is damage;
- the first 3D volume must fit in memory (the size is quoted in GiB when it does not);
- a ``.nii.gz`` is inflated in chunks to its end, so a CRC error or a truncated stream is an error, never data.

Single files are decoded here (``np.frombuffer`` on the checked bytes); pairs and MINC go through ``nibabel.load``
after the same checks. All three give a RAS+ world affine (MINC's world space is RAS as well), converted to LPS.
MINC 2 files are HDF5 and need h5py (a dependency).
"""

from __future__ import annotations

import gzip
import sys
import threading
import warnings
import zlib
from pathlib import Path

import numpy as np

from .atomic import atomic_output
from .errors import CorruptFileError, UnsupportedFormatError, VolumeReadError
from .geometry import FLIP4, guess_ct, make_volume, modality_from_description, orthonormal_direction
from .safety import inflate_prefix, one_line, product, require_fits, require_regular_file

#: Header sizes of NIfTI-1/Analyze and NIfTI-2 (``sizeof_hdr``); a single file's data starts after the header and
#: the 4-byte extension flag.
_NIFTI1, _NIFTI2 = 348, 540


_NIBABEL_IMPORT = threading.Lock()


def _nibabel():
    """nibabel, imported (the first time) without pydicom.

    ``nibabel.nifti1`` imports pydicom, if installed, only to decode DICOM header extensions (code 2) into datasets;
    pydicom in turn imports requests, Pillow and its JPEG plug-ins: about 17 MiB of resident memory in every process
    that reads a NIfTI file (issue 20: the memory of ``render --mode raymarch`` counts it). We never read those
    extensions, so when neither is imported yet nibabel is imported with pydicom hidden and keeps DICOM extensions as
    raw bytes (its documented behaviour without pydicom); pydicom itself imports normally afterwards, and if it is
    already loaded (a DICOM folder was read first) nibabel uses it as usual.

    The hiding is done only while this is the process's one Python thread (the command line): in a process with
    other threads (the window, Dask workers) one of them could import pydicom during those milliseconds and fail,
    so there nibabel is imported as it is.
    """
    if "nibabel" in sys.modules or "pydicom" in sys.modules or threading.active_count() > 1:
        import nibabel

        return nibabel
    with _NIBABEL_IMPORT:
        hidden = "pydicom" not in sys.modules and threading.active_count() == 1
        if hidden:
            sys.modules["pydicom"] = None  # ``import pydicom`` raises ImportError while this is set
        try:
            import nibabel
        finally:
            if hidden and sys.modules.get("pydicom", 0) is None:
                del sys.modules["pydicom"]
    return nibabel


def _gzipped(path: Path) -> bool:
    return path.name.lower().endswith(".gz")


def _header_class(block: bytes, path: Path):
    """The nibabel header class for the first bytes of a file (NIfTI-1, NIfTI-2 or Analyze)."""
    nibabel = _nibabel()

    if len(block) < 4:
        raise CorruptFileError(path, f"the file holds {len(block)} bytes, too few for a NIfTI or Analyze header")
    sizes = {int.from_bytes(block[:4], "little"), int.from_bytes(block[:4], "big")}
    if _NIFTI2 in sizes:
        if block[4:7] not in (b"n+2", b"ni2"):
            raise CorruptFileError(path, "the NIfTI-2 magic ('n+2' at byte 4) is missing or damaged")
        return nibabel.Nifti2Header, _NIFTI2
    if _NIFTI1 in sizes:
        if len(block) >= _NIFTI1 and block[344:347] in (b"n+1", b"ni1"):
            return nibabel.Nifti1Header, _NIFTI1
        return nibabel.AnalyzeHeader, _NIFTI1
    raise CorruptFileError(path, "not a NIfTI or Analyze file (the header size field is neither 348 nor 540)",
                           "The file is damaged or in another format")


def _parse_header(block: bytes, path: Path, warn: list[str]):
    """Header object, shape, dtype and data offset, all checked; raises one-line errors."""
    klass, size = _header_class(block, path)
    if len(block) < size:
        raise CorruptFileError(path, f"the header is truncated ({len(block)} of {size} bytes)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            header = klass(binaryblock=block[:size], check=False)
        except Exception as exc:  # nibabel raises several types for damaged blocks
            raise CorruptFileError(path, f"the header cannot be parsed ({one_line(exc)})") from exc
    warn.extend(f"{path.name}: {one_line(w.message)}" for w in caught)
    dim = [int(v) for v in header["dim"]]
    ndim = dim[0]
    if not 1 <= ndim <= 7:
        raise CorruptFileError(path, f"the header's dim[0] (number of dimensions) is {ndim}; it must be 1 to 7")
    shape = tuple(dim[1:ndim + 1])
    if any(n < 1 for n in shape):
        raise CorruptFileError(path, f"the header declares a size of {'x'.join(map(str, shape))}; every size must "
                                     "be at least 1")
    if ndim < 3:
        raise UnsupportedFormatError(path, f"the image is {ndim}D ({'x'.join(map(str, shape))}); Voxelscope needs a "
                                           "3D volume")
    code = int(header["datatype"])
    try:
        dtype = header.get_data_dtype()
    except Exception as exc:  # KeyError / HeaderDataError for unknown codes
        raise UnsupportedFormatError(path, f"unknown NIfTI/Analyze datatype code {code}",
                                     "The header is damaged or uses a type Voxelscope does not read") from exc
    if dtype.kind not in "iuf" or dtype.fields is not None:
        raise UnsupportedFormatError(path, f"unsupported voxel type {dtype} (datatype {code}); RGB or complex images "
                                           "are not grey-value volumes")
    bitpix = int(header["bitpix"]) if "bitpix" in header else dtype.itemsize * 8
    if bitpix != dtype.itemsize * 8:
        warn.append(f"{path.name}: bitpix {bitpix} disagrees with the datatype ({dtype}); the datatype is used")
    offset = float(header["vox_offset"])
    if not np.isfinite(offset) or offset < 0 or offset != int(offset):
        raise CorruptFileError(path, f"vox_offset {offset} is not a byte offset")
    return header, shape, dtype, int(offset), size


def _affine(header, path: Path) -> np.ndarray:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            affine = np.asarray(header.get_best_affine(), dtype=np.float64)
    except Exception as exc:
        raise CorruptFileError(path, f"the orientation fields are invalid ({one_line(exc)})") from exc
    if affine.shape != (4, 4) or not np.all(np.isfinite(affine)):
        raise CorruptFileError(path, "the orientation (qform/sform/pixdim) is not finite")
    return affine


def _scaled(values: np.ndarray, header) -> np.ndarray:
    """Apply scl_slope/scl_inter (NIfTI: slope 0 or NaN means no scaling)."""
    try:
        slope, inter = header.get_slope_inter()
    except Exception:  # Analyze headers have no scaling fields
        slope, inter = None, None
    slope = None if slope is None or not np.isfinite(slope) or slope == 0 else float(slope)
    inter = None if inter is None or not np.isfinite(inter) else float(inter)
    if slope in (None, 1.0) and inter in (None, 0.0):
        return values
    target = np.float64 if values.dtype.itemsize > 2 else np.float32
    return values.astype(target) * (1.0 if slope is None else slope) + (0.0 if inter is None else inter)


def _first_volume_bytes(shape, dtype) -> tuple[int, int]:
    volume = product(shape[:3]) * dtype.itemsize
    return volume, product(shape) * dtype.itemsize


def read_nifti(path):
    """Read a NIfTI, Analyze or MINC file (see the module notes for what is checked)."""
    path = Path(path)
    name = path.name.lower()
    if name.endswith(".mnc") or name.endswith(".mnc.gz"):
        return _read_with_nibabel(path, "MINC")
    if name.endswith((".hdr", ".img", ".hdr.gz", ".img.gz")):
        return _read_pair(path)
    return _read_single(path)


def _read_single(path: Path):
    """``.nii`` or ``.nii.gz``: header, checks, then the first 3D volume straight from the checked bytes."""
    warn: list[str] = []
    info = require_regular_file(path)
    gz = _gzipped(path)
    try:
        with (gzip.open(path, "rb") if gz else open(path, "rb")) as handle:
            block = handle.read(_NIFTI2)
    except (OSError, EOFError, zlib.error) as exc:
        raise CorruptFileError(path, f"the file cannot be read ({one_line(exc)})", "Re-export or re-copy it") from exc
    header, shape, dtype, offset, size = _parse_header(block, path, warn)
    nibabel = _nibabel()

    if not isinstance(header, nibabel.Nifti1Header):  # Nifti2Header is a subclass
        raise CorruptFileError(path, "the NIfTI magic ('n+1' at byte 344) is missing or damaged",
                               "The file is damaged, or an Analyze header was named .nii")
    if block[344:347] == b"ni1" and size == _NIFTI1:
        raise CorruptFileError(path, "the header says its data is in a separate .img file (NIfTI pair magic 'ni1')",
                               "Open the .hdr with its .img, or fix the magic")
    if offset < size + 4:
        raise CorruptFileError(path, f"vox_offset {offset} lies inside the {size}-byte header",
                               "The header is damaged (a single .nii file needs vox_offset >= {})".format(size + 4))
    volume_bytes, total_bytes = _first_volume_bytes(shape, dtype)
    declared = offset + total_bytes
    described = f"{'x'.join(map(str, shape))} {dtype.name} voxels"
    if gz:
        require_fits(path, volume_bytes, f"the first volume of {described}")
        with open(path, "rb") as handle:
            data, inflated = inflate_prefix(handle, "gzip", path, limit=declared, keep=offset + volume_bytes,
                                            what="the compressed image")
        if inflated < declared:
            raise CorruptFileError(path, f"the image holds {inflated - offset} bytes of voxel data but {described} "
                                         f"need {total_bytes} (truncated)", "Re-export or re-copy the file")
        values = np.frombuffer(data, dtype=dtype, count=product(shape[:3]), offset=offset)
    else:
        if info.st_size != declared:
            state = "truncated" if info.st_size < declared else "longer than the header declares"
            raise CorruptFileError(path, f"the file has {info.st_size} bytes but {described} after a {offset}-byte "
                                         f"header need {declared} ({state})", "Re-export or re-copy the file")
        require_fits(path, volume_bytes, f"the first volume of {described}")
        values = np.fromfile(path, dtype=dtype, count=product(shape[:3]), offset=offset)
    return _finish(values, shape, header, path, warn, "NIfTI")


def _finish(values: np.ndarray, shape, header, path: Path, warn: list[str], fmt: str):
    """Shape (x fastest on disk -> (nz, ny, nx)), scaling, geometry, modality."""
    if len(shape) > 3 and product(shape[3:]) > 1:
        warn.append(f"{path.name}: the image has {product(shape[3:])} volumes (4D); the first one is shown")
    nx, ny, nz = shape[:3]
    values = values.astype(values.dtype.newbyteorder("="), copy=False).reshape(nz, ny, nx)
    array = _scaled(values, header)
    lps = FLIP4 @ _affine(header, path)
    spacing, direction = orthonormal_direction(lps[:3, :3], path, warn)
    description = ""
    if "descrip" in header:
        description = header["descrip"].item().decode("latin-1", "replace")
    if fmt in ("NIfTI", "NIfTI pair") and int(header["sform_code"]) == 0 and int(header["qform_code"]) == 0:
        warn.append(f"{path.name}: no sform or qform; orientation taken from the voxel sizes only")
    modality, units = modality_from_description(description)
    if not modality:
        modality, units = guess_ct(array, warn, path)
    return make_volume(array, spacing, lps[:3, 3], direction, path, "NIfTI" if fmt == "NIfTI pair" else fmt, warn,
                       modality, units)


def _image_file(path: Path) -> tuple[Path, Path]:
    """The header and image file of an Analyze/NIfTI pair, whichever of the two was given."""
    name = path.name
    lower = name.lower()
    gz = ".gz" if lower.endswith(".gz") else ""
    stem = name[: len(name) - len(gz) - 4]
    candidates = {}
    for ext in (".hdr", ".img"):
        options = [path.with_name(stem + e + z) for e in (ext, ext.upper()) for z in ("", ".gz")]
        found = [p for p in options if p.exists()]
        candidates[ext] = found[0] if found else path.with_name(stem + ext)
    return candidates[".hdr"], candidates[".img"]


def _read_pair(path: Path):
    """``.hdr`` + ``.img``: check the header and the image file's size, then read through nibabel."""
    warn: list[str] = []
    header_path, image_path = _image_file(path)
    require_regular_file(header_path, "the header file")
    with (gzip.open(header_path, "rb") if _gzipped(header_path) else open(header_path, "rb")) as handle:
        try:
            block = handle.read(_NIFTI2)
        except (OSError, EOFError, zlib.error) as exc:
            raise CorruptFileError(header_path, f"the header cannot be read ({one_line(exc)})") from exc
    header, shape, dtype, offset, _ = _parse_header(block, header_path, warn)
    if not image_path.exists():
        raise VolumeReadError(image_path, f"the image data file named by {header_path.name} is missing",
                              "Keep the header and its data file (.hdr with .img) together")
    info = require_regular_file(image_path, "the image data file")
    volume_bytes, total_bytes = _first_volume_bytes(shape, dtype)
    described = f"{'x'.join(map(str, shape))} {dtype.name} voxels"
    if not _gzipped(image_path) and info.st_size != offset + total_bytes:
        state = "truncated" if info.st_size < offset + total_bytes else "longer than the header declares"
        raise CorruptFileError(image_path, f"the image file has {info.st_size} bytes but {described} after "
                                           f"{offset} bytes need {offset + total_bytes} ({state})",
                               "Keep the .hdr and .img of the same image together")
    require_fits(image_path, volume_bytes, f"the first volume of {described}")
    nibabel = _nibabel()

    fmt = "NIfTI pair" if isinstance(header, nibabel.Nifti1Header) else "Analyze"
    return _read_with_nibabel(header_path, fmt, warn)


def _read_with_nibabel(path: Path, fmt: str, warn: list[str] | None = None):
    """Pairs and MINC: nibabel's image classes, after the checks; the first 3D volume only."""
    nibabel = _nibabel()

    warn = [] if warn is None else warn
    require_regular_file(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            image = nibabel.load(str(path))
            shape = tuple(int(n) for n in image.shape)
            dtype = np.dtype(image.get_data_dtype())
        except ImportError as exc:  # MINC 2 without h5py
            raise UnsupportedFormatError(path, f"reading this file needs an optional package ({exc.name})",
                                         f"Install {exc.name} into Voxelscope's environment") from exc
        except FileNotFoundError as exc:
            raise VolumeReadError(exc.filename or path, f"a file that {path.name} needs is missing") from exc
        except Exception as exc:  # nibabel, scipy.io.netcdf and h5py raise many types for damaged files
            raise CorruptFileError(path, f"not a readable {fmt} image ({type(exc).__name__}: {one_line(exc)})",
                                   "Re-export or re-copy it") from exc
        if len(shape) < 3:
            raise UnsupportedFormatError(path, f"the image is {len(shape)}D ({shape}); Voxelscope needs a 3D volume")
        if min(shape) < 1:
            raise CorruptFileError(path, f"the image declares a size of {shape}")
        require_fits(path, product(shape[:3]) * dtype.itemsize, f"the first volume of {'x'.join(map(str, shape))}")
        try:
            proxy = image.dataobj
            data = np.asanyarray(proxy[(slice(None),) * 3 + (0,) * (len(shape) - 3)])
        except FileNotFoundError as exc:
            raise VolumeReadError(exc.filename or path, f"the image data file named by {path.name} is missing",
                                  "Keep the header and its data file (.hdr with .img) together") from exc
        except MemoryError as exc:
            raise VolumeReadError(path, "there is not enough memory to read the image") from exc
        except Exception as exc:
            raise CorruptFileError(path, f"the voxel data is damaged or truncated ({one_line(exc)})",
                                   "Re-export or re-copy it") from exc
    warn.extend(f"{path.name}: {one_line(w.message)}" for w in caught if "experimental" not in str(w.message))
    if data.dtype.kind not in "iuf":
        raise UnsupportedFormatError(path, f"unsupported voxel type {data.dtype} (RGB or complex images are not "
                                           "volumes)")
    if len(shape) > 3 and product(shape[3:]) > 1:
        warn.append(f"{path.name}: the image has {product(shape[3:])} volumes (4D); the first one is shown")
    affine = np.asarray(image.affine, dtype=np.float64)
    if not np.all(np.isfinite(affine)):
        raise CorruptFileError(path, "the image orientation is not finite")
    lps = FLIP4 @ affine
    spacing, direction = orthonormal_direction(lps[:3, :3], path, warn)
    description = ""
    header = image.header
    if fmt != "MINC" and "descrip" in header:
        description = header["descrip"].item().decode("latin-1", "replace")
    if fmt == "NIfTI pair" and int(header["sform_code"]) == 0 and int(header["qform_code"]) == 0:
        warn.append(f"{path.name}: no sform or qform; orientation taken from the voxel sizes only")
    array = np.ascontiguousarray(np.asarray(data).transpose(2, 1, 0))
    modality, units = modality_from_description(description)
    if not modality:
        modality, units = guess_ct(array, warn, path)
    return make_volume(array, spacing, lps[:3, 3], direction, path, "NIfTI" if fmt == "NIfTI pair" else fmt, warn,
                       modality, units)


def write_nifti(volume, path, *, overwrite: bool = False) -> Path:
    """Write a NIfTI-1 file (``.nii`` or ``.nii.gz``) with an RAS sform and qform (code 1, scanner)."""
    nibabel = _nibabel()

    path = Path(path)
    affine = FLIP4 @ volume.affine
    data = np.asarray(volume.array).transpose(2, 1, 0)
    image = nibabel.Nifti1Image(data, affine)
    image.header.set_xyzt_units("mm")
    image.set_sform(affine, code=1)
    image.set_qform(affine, code=1)
    image.header["descrip"] = f"modality={volume.modality};units={volume.units}".encode()[:79]
    with atomic_output(path, overwrite=overwrite) as temporary:
        nibabel.save(image, str(temporary))
    return path
