"""Writing a volume as a single-frame DICOM image series (tests, demos and export of synthetic volumes)."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np


def write_dicom_series(
    volume,
    folder,
    *,
    series_uid: str | None = None,
    study_uid: str | None = None,
    rescale_intercept: float | None = None,
    rescale_slope: float = 1.0,
    description: str = "Voxelscope export",
    file_names: Sequence[str] | None = None,
    series_number: int = 1,
    uid_seed: str | None = None,
    patient_name: str = "Phantom^Voxelscope",
    patient_id: str = "VOXELSCOPE-0001",
) -> list[Path]:
    """Write ``volume`` as a single-frame CT/MR image series (one file per k slice), uncompressed.

    Values are stored as ``(value - intercept) / slope`` in unsigned 16 bits when ``rescale_intercept`` is given
    (e.g. ``-1024`` for CT, like most scanners), else as signed 16 bits with intercept 0. UIDs are random unless
    ``uid_seed`` is given: then every UID is derived from it (the same seed writes the same series). Returns the file
    paths.
    """
    from pydicom.dataset import FileDataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    modality = volume.modality or "OT"
    sop_class = {"CT": "1.2.840.10008.5.1.4.1.1.2", "MR": "1.2.840.10008.5.1.4.1.1.4"}.get(
        modality, "1.2.840.10008.5.1.4.1.1.7"
    )

    def new_uid(role: str) -> str:
        return generate_uid(entropy_srcs=[uid_seed, role]) if uid_seed is not None else generate_uid()

    series_uid = series_uid or new_uid("series")
    study_uid = study_uid or new_uid("study")
    frame_uid = new_uid("frame of reference")
    values = np.asarray(volume.array, dtype=np.float64)
    if rescale_intercept is not None:
        stored = np.rint((values - rescale_intercept) / rescale_slope)
        if stored.min() < 0 or stored.max() > 65535:
            raise ValueError("values do not fit unsigned 16 bits with this rescale")
        stored, signed = stored.astype(np.uint16), False
    else:
        stored = np.rint(values / rescale_slope)
        if stored.min() < -32768 or stored.max() > 32767:
            raise ValueError("values do not fit signed 16 bits")
        stored, signed = stored.astype(np.int16), True
    direction = volume.direction
    nx, ny, nz = volume.dimensions
    paths = []
    for k in range(nz):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = sop_class
        meta.MediaStorageSOPInstanceUID = new_uid(f"instance {k}")
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        name = file_names[k] if file_names is not None else f"slice_{k:04d}.dcm"
        path = folder / name
        ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
        ds.SOPClassUID = sop_class
        ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
        ds.StudyInstanceUID = study_uid
        ds.SeriesInstanceUID = series_uid
        ds.FrameOfReferenceUID = frame_uid
        ds.Modality = modality
        ds.SeriesDescription = description
        ds.SeriesNumber = series_number
        ds.InstanceNumber = k + 1
        ds.PatientName = patient_name
        ds.PatientID = patient_id
        ds.ImageType = ["ORIGINAL", "PRIMARY", "AXIAL"]
        position = volume.index_to_world((0, 0, k))
        ds.ImagePositionPatient = [f"{v:.6f}".rstrip("0").rstrip(".") for v in position]
        ds.ImageOrientationPatient = [f"{v:.6f}" for v in np.concatenate([direction[:, 0], direction[:, 1]])]
        ds.PixelSpacing = [f"{volume.spacing[1]:.6f}", f"{volume.spacing[0]:.6f}"]
        ds.SliceThickness = f"{volume.spacing[2]:.6f}"
        ds.Rows, ds.Columns = ny, nx
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.BitsAllocated = 16
        ds.BitsStored = 16
        ds.HighBit = 15
        ds.PixelRepresentation = 1 if signed else 0
        ds.RescaleIntercept = f"{rescale_intercept if rescale_intercept is not None else 0:g}"
        ds.RescaleSlope = f"{rescale_slope:g}"
        if modality == "CT":
            ds.RescaleType = "HU"
        ds.PixelData = np.ascontiguousarray(stored[k]).tobytes()
        ds.save_as(path, enforce_file_format=True)
        paths.append(path)
    return paths
