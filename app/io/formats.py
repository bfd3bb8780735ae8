"""Readers and writers for NIfTI/Analyze/MINC, NRRD, MetaImage, VTK images and raw files.

All readers return an :class:`app.volume.Volume` in LPS millimetres with the array in ``(nz, ny, nx)`` order, and
check what a header declares against the file before allocating (see :mod:`app.io.safety`).

- NIfTI, Analyze and MINC: :mod:`app.io.nifti` (nibabel's headers; RAS converted to LPS).
- NRRD: :mod:`app.io.nrrdfile` (pynrrd parses the header; data read and checked there).
- MetaImage (``.mha``/``.mhd``): the header is parsed and checked by :mod:`app.io.metaimage`, then the pixels go
  through ``vtkMetaImageReader``; the geometry is taken from the header with ITK's conventions (world coordinates
  are LPS; ``TransformMatrix`` lists the direction of each axis in turn), the reference for this format.
- VTK XML images (``.vti``) and legacy VTK files (``.vtk``): checked by :mod:`app.io.vtkimage`, then read by VTK's
  readers, keeping origin, spacing and direction; their coordinates are taken as LPS.
- Raw files need their layout from the caller (:class:`RawLayout`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from vtkmodules.vtkCommonCore import vtkStringArray
from vtkmodules.vtkCommonDataModel import vtkImageData

from algorithms.common.vtk_bridge import VTKError, array_from_image, run_algorithm

from ..volume import Volume
from .atomic import atomic_output
from .errors import CorruptFileError, UnsupportedFormatError
from .geometry import guess_ct, make_volume, orthonormal_direction
from .metaimage import parse_header as parse_metaimage_header
from .metaimage import geometry as metaimage_geometry
from .metaimage import write_metaimage
from .nifti import read_nifti, write_nifti
from .nrrdfile import read_nrrd, write_nrrd
from .safety import product, require_fits, require_regular_file
from .vtk_writing import write_with_vtk
from .vtkimage import check_legacy_vtk, check_vti

__all__ = [
    "RawLayout", "read_metaimage", "read_nifti", "read_nrrd", "read_raw", "read_vtk_image", "write_metaimage",
    "write_nifti", "write_nrrd", "write_vti",
]


# ----------------------------------------------------------------------------------------------------------------
# MetaImage
# ----------------------------------------------------------------------------------------------------------------
def read_metaimage(path):
    """MetaImage (``.mha`` or ``.mhd`` + data file): header checked here, pixels through ``vtkMetaImageReader``."""
    from vtkmodules.vtkIOImage import vtkMetaImageReader

    path = Path(path)
    warn: list[str] = []
    header = parse_metaimage_header(path)
    axes, origin, _ = metaimage_geometry(header)
    reader = vtkMetaImageReader()
    reader.SetFileName(str(path))
    try:
        image = run_algorithm(reader)
    except VTKError as exc:
        raise CorruptFileError(path, f"the pixel data could not be read ({exc})", "The file may be truncated") from exc
    if tuple(image.GetDimensions()) != tuple(header.dims):
        raise CorruptFileError(path, f"read {image.GetDimensions()} voxels but the header says {list(header.dims)}")
    values = np.array(array_from_image(image), copy=True)
    if values.dtype != header.dtype.newbyteorder("="):
        raise CorruptFileError(path, f"read {values.dtype} voxels but the header says {header.dtype.name}")
    spacing, direction = orthonormal_direction(axes, path, warn)
    modality = {"MET_MOD_CT": "CT", "MET_MOD_MR": "MR"}.get(header.fields.get("Modality", ""), "")
    units = "HU" if modality == "CT" else ""
    if not modality:
        modality, units = guess_ct(values, warn, path)
    return make_volume(values, spacing, origin, direction, path, "MetaImage", warn, modality, units)


# ----------------------------------------------------------------------------------------------------------------
# VTK images
# ----------------------------------------------------------------------------------------------------------------
def read_vtk_image(path):
    """VTK XML image (``.vti``) or legacy VTK (``.vtk``) holding structured points, checked before VTK reads it."""
    from vtkmodules.vtkIOLegacy import vtkDataSetReader
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader

    path = Path(path)
    if path.suffix.lower() == ".vti":
        check_vti(path)
        reader = vtkXMLImageDataReader()
        reader.SetFileName(str(path))
        source_format = "VTK XML image"
    else:
        check_legacy_vtk(path)
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
                                     "Open meshes with Voxelscope's mesh reader; volumes need an image file")
    if output.GetNumberOfPoints() == 0 or output.GetPointData().GetScalars() is None:
        raise CorruptFileError(path, "the image has no point scalars")
    scalars = output.GetPointData().GetScalars()
    if scalars.GetNumberOfComponents() != 1:
        raise UnsupportedFormatError(path, f"the image has {scalars.GetNumberOfComponents()} components per voxel; "
                                           "Voxelscope needs grey values")
    if scalars.GetNumberOfTuples() != output.GetNumberOfPoints():
        raise CorruptFileError(path, f"the image has {scalars.GetNumberOfTuples()} values for "
                                     f"{output.GetNumberOfPoints()} points")
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
    try:
        volume = Volume.from_vtk(output, modality=modality, units=units)
    except ValueError as exc:  # spacing, origin or direction the volume model refuses
        raise CorruptFileError(path, f"the image geometry is invalid ({exc})") from exc
    warn: list[str] = []
    if not modality:
        volume.modality, volume.units = guess_ct(volume.array, warn, path)
    volume.metadata.update({"source_format": source_format, "source_path": str(path), "warnings": warn})
    return volume


def write_vti(volume, path, *, overwrite: bool = False) -> Path:
    """Write a VTK XML image (zlib-compressed, appended raw) with origin, spacing, direction, modality and units.

    VTK's writer reports a full disk only through its error code (and by printing), so the error code is checked
    and VTK's messages are caught: a failed write never lands at ``path``.
    """
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    path = Path(path)
    image = volume.to_vtk()
    for name, value in (("modality", volume.modality), ("units", volume.units)):
        array = vtkStringArray()
        array.SetName(name)
        array.InsertNextValue(value)
        image.GetFieldData().AddArray(array)
    with atomic_output(path, overwrite=overwrite) as temporary:
        write_with_vtk(vtkXMLImageDataWriter, image, temporary)
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

    def checked_dtype(self) -> np.dtype:
        """The voxel type with its byte order; ``ValueError`` for layouts that make no sense."""
        try:
            dtype = np.dtype(self.dtype)
        except TypeError as exc:
            raise ValueError(f"unknown raw data type {self.dtype!r}; use e.g. uint8, int16, float32") from exc
        if dtype.kind not in "iuf":
            raise ValueError(f"raw data type must be an integer or float type, got {self.dtype!r}")
        if self.byte_order not in ("little", "big"):
            raise ValueError(f"byte order must be 'little' or 'big', got {self.byte_order!r}")
        if len(self.dimensions) != 3 or min(int(v) for v in self.dimensions) < 1:
            raise ValueError(f"raw dimensions must be three positive numbers, got {self.dimensions}")
        if self.header_bytes < 0:
            raise ValueError(f"the raw header size must not be negative, got {self.header_bytes}")
        return dtype.newbyteorder("<" if self.byte_order == "little" else ">")


def read_raw(path, layout: RawLayout):
    """Read a raw file with an explicit :class:`RawLayout`; identity direction."""
    path = Path(path)
    dtype = layout.checked_dtype()
    nx, ny, nz = (int(v) for v in layout.dimensions)
    needed = layout.header_bytes + product((nx, ny, nz)) * dtype.itemsize
    size = require_regular_file(path).st_size
    if size < needed:
        raise CorruptFileError(
            path, f"the file has {size} bytes but {nx}x{ny}x{nz} {layout.dtype} voxels after a {layout.header_bytes}-byte "
                  f"header need {needed}", "Check the dimensions, data type and header size",
        )
    require_fits(path, needed - layout.header_bytes, f"{nx}x{ny}x{nz} {layout.dtype} voxels")
    warn = []
    if size > needed:
        warn.append(f"{path.name}: {size - needed} bytes after the voxel data were ignored")
    values = np.fromfile(path, dtype=dtype, count=nx * ny * nz, offset=layout.header_bytes)
    values = values.astype(dtype.newbyteorder("=")).reshape(nz, ny, nx)
    return make_volume(values, layout.spacing, layout.origin, np.eye(3), path, "raw", warn, layout.modality,
                       layout.units)
