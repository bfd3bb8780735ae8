"""Readers and writers for NIfTI/Analyze, NRRD, MetaImage, VTK images and raw files.

All readers return an :class:`app.volume.Volume` in LPS millimetres with the array in ``(nz, ny, nx)`` order.

- NIfTI, Analyze and MINC go through nibabel; their RAS affine is converted to LPS (x and y negated).
- MetaImage (``.mha``/``.mhd``) pixels go through ``vtkMetaImageReader``; its geometry is taken from the header
  with ITK's conventions (world coordinates are LPS; ``TransformMatrix`` lists the direction of each axis in
  turn), the reference for this format.
- VTK XML images (``.vti``) and legacy VTK files (``.vtk``) go through VTK's readers, keeping origin, spacing and
  direction; their coordinates are taken as LPS.
- NRRD (``.nrrd``/``.nhdr``) is parsed here: ``vtkNrrdReader`` drops ``space directions`` and misreads some
  valid headers (measured with VTK 9.7: a gzip-encoded 3D short volume came back as a 5x6x1 image), so it cannot
  be trusted with patient geometry. Supported encodings: raw, gzip, bzip2, ascii; detached headers; spaces
  LPS, RAS, LAS and scanner-xyz (taken as LPS).
- Raw files need their layout from the caller (:class:`RawLayout`).
"""

from __future__ import annotations

import bz2
import gzip
import re
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .atomic import atomic_output
from .errors import CorruptFileError, UnsupportedFormatError, VolumeReadError, VolumeWriteError

LPS_FROM_RAS = np.diag([-1.0, -1.0, 1.0])  # also RAS from LPS: the flip is its own inverse
_FLIP4 = np.diag([-1.0, -1.0, 1.0, 1.0])


def _orthonormal_direction(axes: np.ndarray, path: Path, warn: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Split a 3x3 matrix whose columns are axis vectors (mm per voxel) into spacing and direction.

    Sheared axes (not perpendicular) are replaced by the nearest orthonormal frame with a warning.
    """
    spacing = np.linalg.norm(axes, axis=0)
    if np.any(spacing <= 0) or not np.all(np.isfinite(spacing)):
        raise CorruptFileError(path, f"the voxel axes have zero or invalid length ({spacing.tolist()})")
    direction = axes / spacing
    if not np.allclose(direction.T @ direction, np.eye(3), atol=1e-4):
        u, _, vt = np.linalg.svd(direction)
        direction = u @ vt
        warn.append(f"{path.name}: the voxel axes are sheared; the nearest orthogonal orientation is used")
    return spacing, direction


def _volume(array, spacing, origin, direction, path: Path, source_format: str, warn: list[str], modality="", units="",
            extra: dict[str, Any] | None = None):
    from ..volume import Volume

    metadata = {"source_format": source_format, "source_path": str(path), "warnings": warn}
    metadata.update(extra or {})
    return Volume(
        np.ascontiguousarray(array), spacing=tuple(spacing), origin=tuple(origin), direction=direction,
        modality=modality, units=units, metadata=metadata,
    )


def _modality_from_description(description: str) -> tuple[str, str]:
    """Modality and units that Voxelscope's own writers record in a free-text header field."""
    match = re.search(r"modality=(\w*);units=(\w*)", description or "")
    return (match.group(1), match.group(2)) if match else ("", "")


def _guess_ct(array: np.ndarray, warn: list[str], path: Path) -> tuple[str, str]:
    """Integer data spanning air (about -1000) to bone looks like CT in HU; say so instead of guessing silently."""
    if array.dtype.kind not in "iu" or array.size == 0:
        return "", ""
    lo, hi = int(array.min()), int(array.max())
    if -1100 <= lo <= -900 and hi >= 300:
        warn.append(f"{path.name}: values {lo}..{hi} look like CT in Hounsfield units; modality set to CT")
        return "CT", "HU"
    return "", ""


# ----------------------------------------------------------------------------------------------------------------
# NIfTI / Analyze
# ----------------------------------------------------------------------------------------------------------------
def read_nifti(path):
    """NIfTI-1/2 (``.nii``, ``.nii.gz``), Analyze 7.5 (``.hdr``/``.img``) or MINC (``.mnc``) through nibabel.

    All three give nibabel a RAS+ world affine (MINC's world space is RAS as well).
    """
    import nibabel

    path = Path(path)
    warn: list[str] = []
    try:
        image = nibabel.load(str(path))
    except nibabel.filebasedimages.ImageFileError as exc:
        raise CorruptFileError(path, f"not a readable NIfTI/Analyze/MINC image ({exc})") from exc
    except ImportError as exc:  # MINC2 needs h5py
        raise UnsupportedFormatError(path, f"reading this file needs an optional package ({exc.name})",
                                     f"Install {exc.name} into Voxelscope's environment") from exc
    except (EOFError, OSError, ValueError, zlib.error) as exc:
        raise CorruptFileError(path, f"the file is damaged or truncated ({type(exc).__name__}: {exc})",
                               "Re-export or re-copy it") from exc
    shape = image.shape
    if len(shape) < 3:
        raise UnsupportedFormatError(path, f"the image is {len(shape)}D ({shape}); Voxelscope needs a 3D volume")
    try:
        data = np.asanyarray(image.dataobj)
    except FileNotFoundError as exc:
        raise VolumeReadError(exc.filename or path, f"the image data file named by {path.name} is missing",
                              "Keep the header and its data file (.hdr with .img) together") from exc
    except (EOFError, OSError, ValueError, zlib.error) as exc:
        raise CorruptFileError(path, f"the voxel data is damaged or truncated ({exc})", "Re-export or re-copy it") from exc
    if data.ndim > 3:
        extra = int(np.prod(data.shape[3:]))
        if extra > 1:
            warn.append(f"{path.name}: the image has {extra} volumes (4D); the first one is shown")
        data = data.reshape(data.shape[:3] + (-1,))[..., 0]
    if data.dtype.kind not in "iuf":
        raise UnsupportedFormatError(path, f"unsupported voxel type {data.dtype} (RGB or complex images are not volumes)")
    header = image.header
    affine = np.asarray(image.affine, dtype=np.float64)
    description = ""
    if isinstance(image, (nibabel.Nifti1Image, nibabel.Nifti2Image)):
        if int(header["sform_code"]) == 0 and int(header["qform_code"]) == 0:
            warn.append(f"{path.name}: no sform or qform; orientation taken from the voxel sizes only")
        description = header["descrip"].item().decode("latin-1", "replace")
    elif isinstance(image, nibabel.AnalyzeImage):
        description = header["descrip"].item().decode("latin-1", "replace")
    lps = _FLIP4 @ affine
    spacing, direction = _orthonormal_direction(lps[:3, :3], path, warn)
    modality, units = _modality_from_description(description)
    array = np.ascontiguousarray(np.asarray(data).transpose(2, 1, 0))
    if not modality:
        modality, units = _guess_ct(array, warn, path)
    if isinstance(image, (nibabel.Nifti1Image, nibabel.Nifti2Image)):
        fmt = "NIfTI"
    elif isinstance(image, (nibabel.Minc1Image, nibabel.Minc2Image)):
        fmt = "MINC"
    else:
        fmt = "Analyze"
    return _volume(array, spacing, lps[:3, 3], direction, path, fmt, warn, modality, units)


def write_nifti(volume, path, *, overwrite: bool = False) -> Path:
    """Write a NIfTI-1 file (``.nii`` or ``.nii.gz``) with an RAS sform and qform (code 1, scanner)."""
    import nibabel

    path = Path(path)
    affine = _FLIP4 @ volume.affine
    data = np.asarray(volume.array).transpose(2, 1, 0)
    image = nibabel.Nifti1Image(data, affine)
    image.header.set_xyzt_units("mm")
    image.set_sform(affine, code=1)
    image.set_qform(affine, code=1)
    image.header["descrip"] = f"modality={volume.modality};units={volume.units}".encode()[:79]
    with atomic_output(path, overwrite=overwrite) as temporary:
        nibabel.save(image, str(temporary))
    return path


# ----------------------------------------------------------------------------------------------------------------
# NRRD
# ----------------------------------------------------------------------------------------------------------------
_NRRD_TYPES = {
    "signed char": "i1", "int8": "i1", "int8_t": "i1", "uchar": "u1", "unsigned char": "u1", "uint8": "u1",
    "uint8_t": "u1", "short": "i2", "short int": "i2", "signed short": "i2", "signed short int": "i2", "int16": "i2",
    "int16_t": "i2", "ushort": "u2", "unsigned short": "u2", "unsigned short int": "u2", "uint16": "u2",
    "uint16_t": "u2", "int": "i4", "signed int": "i4", "int32": "i4", "int32_t": "i4", "uint": "u4",
    "unsigned int": "u4", "uint32": "u4", "uint32_t": "u4", "longlong": "i8", "long long": "i8", "int64": "i8",
    "int64_t": "i8", "ulonglong": "u8", "unsigned long long": "u8", "uint64": "u8", "uint64_t": "u8",
    "float": "f4", "double": "f8",
}
_NRRD_SPACES = {
    "left-posterior-superior": np.eye(3), "lps": np.eye(3),
    "right-anterior-superior": LPS_FROM_RAS, "ras": LPS_FROM_RAS,
    "left-anterior-superior": np.diag([1.0, -1.0, 1.0]), "las": np.diag([1.0, -1.0, 1.0]),
    "scanner-xyz": np.eye(3), "3d-right-handed": np.eye(3),
}


def _nrrd_vector(text: str) -> np.ndarray | None:
    text = text.strip()
    if text.lower() == "none":
        return None
    numbers = re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", text)
    return np.array([float(n) for n in numbers])


def read_nrrd(path):
    """NRRD with attached (``.nrrd``) or detached (``.nhdr``) data."""
    path = Path(path)
    warn: list[str] = []
    raw = path.read_bytes()
    if not raw.startswith(b"NRRD"):
        raise CorruptFileError(path, "the file does not start with the NRRD magic 'NRRD000x'")
    header_end = raw.find(b"\n\n")
    if header_end < 0:
        header_end = raw.find(b"\r\n\r\n")
        skip = 4
    else:
        skip = 2
    if header_end < 0 and path.suffix.lower() != ".nhdr":
        raise CorruptFileError(path, "the NRRD header has no terminating blank line (the file may be truncated)")
    header_text = raw[: header_end if header_end >= 0 else len(raw)].decode("latin-1")
    fields: dict[str, str] = {}
    for line in header_text.splitlines()[1:]:
        if not line or line.startswith("#"):
            continue
        if ":=" in line:
            continue  # key/value pairs, not fields
        if ":" in line:
            key, value = line.split(":", 1)
            fields[key.strip().lower()] = value.strip()

    def need(name):
        if name not in fields:
            raise CorruptFileError(path, f"the NRRD header lacks the required field '{name}'")
        return fields[name]

    type_name = need("type").lower()
    if type_name not in _NRRD_TYPES:
        raise UnsupportedFormatError(path, f"unsupported NRRD type '{type_name}'")
    dimension = int(need("dimension"))
    sizes = [int(v) for v in need("sizes").split()]
    if len(sizes) != dimension:
        raise CorruptFileError(path, f"'sizes' lists {len(sizes)} values for dimension {dimension}")
    spatial = list(range(dimension))
    directions = None
    if "space directions" in fields:
        parts = re.findall(r"\([^)]*\)|none", fields["space directions"], flags=re.IGNORECASE)
        vectors = [_nrrd_vector(p) for p in parts]
        if len(vectors) != dimension:
            raise CorruptFileError(path, "'space directions' does not list one entry per axis")
        spatial = [i for i, v in enumerate(vectors) if v is not None]
        directions = np.column_stack([vectors[i] for i in spatial]) if spatial else None
    if len(spatial) != 3 or dimension > 4:
        raise UnsupportedFormatError(path, f"the NRRD has {len(spatial)} spatial axes; Voxelscope needs exactly three")
    non_spatial = [i for i in range(dimension) if i not in spatial]
    if non_spatial and sizes[non_spatial[0]] > 1 and non_spatial[0] != 0:
        raise UnsupportedFormatError(path, "only a leading non-spatial (component) axis is supported")
    space_name = fields.get("space", "").lower()
    to_lps = _NRRD_SPACES.get(space_name)
    if space_name and to_lps is None:
        raise UnsupportedFormatError(path, f"unsupported NRRD space '{fields['space']}'")
    if to_lps is None:
        to_lps = np.eye(3)
        if directions is None:
            warn.append(f"{path.name}: no 'space' field; coordinates taken as LPS")
    if directions is None:
        spacings = fields.get("spacings")
        values = [float(v) if v.lower() != "nan" else 1.0 for v in spacings.split()] if spacings else [1.0] * dimension
        directions = np.diag([values[i] for i in spatial])
        if not spacings:
            warn.append(f"{path.name}: no spacing in the header; 1 mm assumed")
    origin = _nrrd_vector(fields.get("space origin", "(0,0,0)"))
    if origin is None or len(origin) != 3:
        origin = np.zeros(3)
    axes = to_lps @ directions
    spacing, direction = _orthonormal_direction(axes, path, warn)

    encoding = fields.get("encoding", "raw").lower()
    data_file = fields.get("data file") or fields.get("datafile")
    if data_file:
        if data_file.startswith("LIST") or "%" in data_file:
            raise UnsupportedFormatError(path, "NRRD data split over several files is not supported")
        data_path = (path.parent / data_file).resolve()
        try:
            payload = data_path.read_bytes()
        except OSError as exc:
            raise VolumeReadError(data_path, f"the data file named by {path.name} cannot be read ({exc.strerror})",
                                  "Keep the .nhdr next to its data file") from exc
    else:
        payload = raw[header_end + skip:]
    line_skip = int(fields.get("line skip", fields.get("lineskip", 0)))
    for _ in range(line_skip):
        payload = payload[payload.find(b"\n") + 1:]
    byte_skip = int(fields.get("byte skip", fields.get("byteskip", 0)))
    dtype = np.dtype(_NRRD_TYPES[type_name])
    if dtype.itemsize > 1:
        endian = fields.get("endian", "little").lower()
        dtype = dtype.newbyteorder("<" if endian == "little" else ">")
    count = int(np.prod(sizes))
    try:
        if encoding in ("raw",):
            data = payload[byte_skip:] if byte_skip >= 0 else payload[-count * dtype.itemsize:]
        elif encoding in ("gzip", "gz"):
            data = gzip.decompress(payload)
        elif encoding in ("bzip2", "bz2"):
            data = bz2.decompress(payload)
        elif encoding in ("ascii", "text", "txt"):
            values = np.array(payload.decode("latin-1").split(), dtype=np.float64)
            data = values.astype(dtype).tobytes()
        else:
            raise UnsupportedFormatError(path, f"unsupported NRRD encoding '{encoding}'")
    except (OSError, EOFError, zlib.error, ValueError) as exc:
        raise CorruptFileError(path, f"the {encoding} data is damaged or truncated ({exc})", "Re-export the file") from exc
    if len(data) < count * dtype.itemsize:
        raise CorruptFileError(
            path, f"the data holds {len(data)} bytes but the header needs {count * dtype.itemsize}",
            "The file is truncated; re-export or re-copy it",
        )
    values = np.frombuffer(data[: count * dtype.itemsize], dtype=dtype).astype(dtype.newbyteorder("="))
    values = values.reshape(sizes[::-1])  # NRRD's first axis is fastest
    if non_spatial:
        if sizes[non_spatial[0]] > 1:
            warn.append(f"{path.name}: {sizes[non_spatial[0]]} components per voxel; the first one is shown")
        values = values[..., 0]
    modality, units = _modality_from_description(fields.get("content", ""))
    if not modality:
        modality, units = _guess_ct(values, warn, path)
    return _volume(values, spacing, to_lps @ origin, direction, path, "NRRD", warn, modality, units)


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
        temporary.write_bytes(header.encode("latin-1") + gzip.compress(array.tobytes(), compresslevel=6))
    return path


# ----------------------------------------------------------------------------------------------------------------
# MetaImage
# ----------------------------------------------------------------------------------------------------------------
def _metaimage_header(path: Path) -> dict[str, str]:
    fields: dict[str, str] = {}
    with open(path, "rb") as handle:
        for _ in range(200):
            line = handle.readline()
            if not line:
                break
            text = line.decode("latin-1").strip()
            if "=" not in text:
                continue
            key, value = text.split("=", 1)
            fields[key.strip()] = value.strip()
            if key.strip() == "ElementDataFile":
                break
    return fields


def read_metaimage(path):
    """MetaImage (``.mha`` or ``.mhd`` + data file): pixels through ``vtkMetaImageReader``, geometry from the header."""
    from vtkmodules.vtkIOImage import vtkMetaImageReader

    from algorithms._vtk import VTKError, array_from_image, run_algorithm

    path = Path(path)
    warn: list[str] = []
    fields = _metaimage_header(path)
    if "NDims" not in fields or "DimSize" not in fields:
        raise CorruptFileError(path, "not a MetaImage header (NDims and DimSize are missing)")
    if int(fields["NDims"]) != 3:
        raise UnsupportedFormatError(path, f"the image has {fields['NDims']} dimensions; Voxelscope needs 3")
    if int(fields.get("ElementNumberOfChannels", "1")) != 1:
        raise UnsupportedFormatError(path, "the image has several channels per voxel; Voxelscope needs grey values")
    data_file = fields.get("ElementDataFile", "")
    if data_file and data_file != "LOCAL" and not data_file.startswith("LIST"):
        if "%" not in data_file and not (path.parent / data_file).exists():
            raise VolumeReadError(path.parent / data_file, f"the data file named by {path.name} does not exist",
                                  "Keep the .mhd next to its data file")
    reader = vtkMetaImageReader()
    reader.SetFileName(str(path))
    try:
        image = run_algorithm(reader)
    except VTKError as exc:
        raise CorruptFileError(path, f"the pixel data could not be read ({exc})", "The file may be truncated") from exc
    dims = [int(v) for v in fields["DimSize"].split()]
    if tuple(image.GetDimensions()) != tuple(dims):
        raise CorruptFileError(path, f"read {image.GetDimensions()} voxels but the header says {dims}")
    values = np.array(array_from_image(image), copy=True)
    spacing = [float(v) for v in fields.get("ElementSpacing", fields.get("ElementSize", "1 1 1")).split()]
    origin_text = fields.get("Offset") or fields.get("Position") or fields.get("Origin") or "0 0 0"
    origin = np.array([float(v) for v in origin_text.split()])
    matrix_text = fields.get("TransformMatrix") or fields.get("Rotation") or fields.get("Orientation")
    direction = np.eye(3)
    if matrix_text:
        # ITK writes the direction of axis 0, then axis 1, then axis 2: the rows of the text are our columns.
        direction = np.array([float(v) for v in matrix_text.split()]).reshape(3, 3).T
    axes = direction * np.asarray(spacing)[None, :]
    spacing, direction = _orthonormal_direction(axes, path, warn)
    modality = {"MET_MOD_CT": "CT", "MET_MOD_MR": "MR"}.get(fields.get("Modality", ""), "")
    units = "HU" if modality == "CT" else ""
    if not modality:
        modality, units = _guess_ct(values, warn, path)
    return _volume(values, spacing, origin, direction, path, "MetaImage", warn, modality, units)


def write_metaimage(volume, path, *, overwrite: bool = False) -> Path:
    """Write a MetaImage with ITK's geometry conventions: ``.mha`` (one file) or ``.mhd`` (+ ``.zraw``)."""
    path = Path(path)
    array = np.ascontiguousarray(volume.array)
    types = {"i1": "MET_CHAR", "u1": "MET_UCHAR", "i2": "MET_SHORT", "u2": "MET_USHORT", "i4": "MET_INT",
             "u4": "MET_UINT", "i8": "MET_LONG_LONG", "u8": "MET_ULONG_LONG", "f4": "MET_FLOAT", "f8": "MET_DOUBLE"}
    code = array.dtype.str[1:]
    if code not in types:
        raise VolumeWriteError(f"{path}: MetaImage cannot store {array.dtype}")
    payload = zlib.compress(array.astype(array.dtype.newbyteorder("<")).tobytes(), 6)
    detached = path.suffix.lower() == ".mhd"
    data_name = path.with_suffix(".zraw").name
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
    header += [f"ElementType = {types[code]}", f"ElementDataFile = {data_name if detached else 'LOCAL'}"]
    text = ("\n".join(header) + "\n").encode("latin-1")
    if detached:
        with atomic_output(path.with_suffix(".zraw"), overwrite=overwrite) as temporary:
            temporary.write_bytes(payload)
        with atomic_output(path, overwrite=overwrite) as temporary:
            temporary.write_bytes(text)
    else:
        with atomic_output(path, overwrite=overwrite) as temporary:
            temporary.write_bytes(text + payload)
    return path


# ----------------------------------------------------------------------------------------------------------------
# VTK images
# ----------------------------------------------------------------------------------------------------------------
def read_vtk_image(path):
    """VTK XML image (``.vti``) or legacy VTK (``.vtk``) holding structured points."""
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkIOLegacy import vtkDataSetReader
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader

    from algorithms._vtk import VTKError, run_algorithm

    from ..volume import Volume

    path = Path(path)
    if path.suffix.lower() == ".vti":
        reader = vtkXMLImageDataReader()
        reader.SetFileName(str(path))
        source_format = "VTK XML image"
    else:
        reader = vtkDataSetReader()
        reader.SetFileName(str(path))
        source_format = "VTK legacy"
    try:
        output = run_algorithm(reader)
    except VTKError as exc:
        raise CorruptFileError(path, f"VTK could not read the file ({exc})", "It may be damaged or truncated") from exc
    if output is None or not isinstance(output, vtkImageData):
        kind = output.GetClassName() if output is not None else "nothing"
        raise UnsupportedFormatError(path, f"the file holds {kind}, not an image volume",
                                     "Open meshes in a mesh viewer; Voxelscope reads volumes")
    if output.GetNumberOfPoints() == 0 or output.GetPointData().GetScalars() is None:
        raise CorruptFileError(path, "the image has no point scalars")
    scalars = output.GetPointData().GetScalars()
    if scalars.GetNumberOfComponents() != 1:
        raise UnsupportedFormatError(path, f"the image has {scalars.GetNumberOfComponents()} components per voxel; "
                                           "Voxelscope needs grey values")
    dims = output.GetDimensions()
    if min(dims) < 2:
        raise UnsupportedFormatError(path, f"the image is {dims[0]}x{dims[1]}x{dims[2]}; a volume needs 2 or more voxels on every axis")
    field_data = output.GetFieldData()
    modality = units = ""
    for name in ("modality", "units"):
        array = field_data.GetAbstractArray(name) if field_data is not None else None
        if array is not None and array.GetNumberOfValues() > 0:
            if name == "modality":
                modality = str(array.GetValue(0))
            else:
                units = str(array.GetValue(0))
    volume = Volume.from_vtk(output, modality=modality, units=units)
    warn: list[str] = []
    if not modality:
        volume.modality, volume.units = _guess_ct(volume.array, warn, path)
    volume.metadata.update({"source_format": source_format, "source_path": str(path), "warnings": warn})
    return volume


def write_vti(volume, path, *, overwrite: bool = False) -> Path:
    """Write a VTK XML image (zlib-compressed) with origin, spacing, direction, modality and units."""
    from vtkmodules.vtkCommonCore import vtkStringArray
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    path = Path(path)
    image = volume.to_vtk()
    for name, value in (("modality", volume.modality), ("units", volume.units)):
        array = vtkStringArray()
        array.SetName(name)
        array.InsertNextValue(value)
        image.GetFieldData().AddArray(array)
    with atomic_output(path, overwrite=overwrite) as temporary:
        writer = vtkXMLImageDataWriter()
        writer.SetFileName(str(temporary))
        writer.SetInputData(image)
        writer.SetCompressorTypeToZLib()
        if writer.Write() != 1:
            raise VolumeWriteError(f"{path}: VTK could not write the image")
    return path


# ----------------------------------------------------------------------------------------------------------------
# Raw
# ----------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RawLayout:
    """How a headerless raw file is laid out.

    ``dimensions`` is ``(nx, ny, nz)`` with x fastest in the file; ``dtype`` a NumPy type name such as
    ``"int16"``; ``byte_order`` "little" or "big"; ``header_bytes`` bytes to skip at the start.
    """

    dimensions: tuple[int, int, int]
    dtype: str
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    byte_order: str = "little"
    header_bytes: int = 0
    modality: str = ""
    units: str = ""


def read_raw(path, layout: RawLayout):
    """Read a raw file with an explicit :class:`RawLayout`; identity direction."""
    path = Path(path)
    try:
        dtype = np.dtype(layout.dtype)
    except TypeError as exc:
        raise ValueError(f"unknown raw data type {layout.dtype!r}; use e.g. uint8, int16, float32") from exc
    if dtype.kind not in "iuf":
        raise ValueError(f"raw data type must be an integer or float type, got {layout.dtype!r}")
    if layout.byte_order not in ("little", "big"):
        raise ValueError(f"byte order must be 'little' or 'big', got {layout.byte_order!r}")
    nx, ny, nz = (int(v) for v in layout.dimensions)
    if min(nx, ny, nz) < 1:
        raise ValueError(f"raw dimensions must be positive, got {layout.dimensions}")
    dtype = dtype.newbyteorder("<" if layout.byte_order == "little" else ">")
    needed = layout.header_bytes + nx * ny * nz * dtype.itemsize
    size = path.stat().st_size
    if size < needed:
        raise CorruptFileError(
            path, f"the file has {size} bytes but {nx}x{ny}x{nz} {layout.dtype} voxels after a {layout.header_bytes}-byte "
                  f"header need {needed}", "Check the dimensions, data type and header size",
        )
    warn = []
    if size > needed:
        warn.append(f"{path.name}: {size - needed} bytes after the voxel data were ignored")
    values = np.fromfile(path, dtype=dtype, count=nx * ny * nz, offset=layout.header_bytes)
    values = values.astype(dtype.newbyteorder("=")).reshape(nz, ny, nx)
    return _volume(values, layout.spacing, layout.origin, np.eye(3), path, "raw", warn, layout.modality, layout.units)
