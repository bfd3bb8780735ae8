"""Builders of scanner-like DICOM folders for the reader tests (pydicom writes real files)."""

from __future__ import annotations

import contextlib
import math
import shutil
import warnings
from pathlib import Path

import numpy as np

from app.datasets import ct_head_phantom
from app.io import write_dicom_series
from app.volume import Volume


def small_ct(shape=(12, 40, 36), spacing=(1.5, 1.25, 3.0)) -> Volume:
    """A small CT phantom volume in HU with non-cubic voxels and different sizes per axis."""
    volume = ct_head_phantom(shape=shape, spacing=spacing)
    volume.origin = (-20.0, 35.0, 110.0)
    return volume


def shuffled_names(count: int, seed: int = 7) -> list[str]:
    """Scanner-style file names (IM0001...) assigned to slices in a random order."""
    rng = np.random.default_rng(seed)
    order = rng.permutation(count)
    return [f"IM{int(i) + 1:04d}" for i in order]


def write_scanner_folder(volume: Volume, folder: Path, *, with_scout: bool = True) -> dict:
    """A folder like a scanner export: shuffled file names, RescaleIntercept -1024, plus a scout from another series."""
    names = shuffled_names(volume.dimensions[2])
    write_dicom_series(volume, folder, rescale_intercept=-1024, file_names=names, description="HEAD 3.0 mm")
    info = {"names": names}
    if with_scout:
        # A sagittal localizer: one 64x48 image, another series, another orientation.
        scout = Volume(
            np.full((2, 48, 64), -1000, dtype=np.int16),
            spacing=(2.0, 2.0, 1.0),
            origin=(0.0, -50.0, 150.0),
            direction=np.column_stack([(0, 1, 0), (0, 0, -1), (-1, 0, 0)]),
            modality="CT",
            units="HU",
        )
        scout_dir = folder.parent / (folder.name + "_scout")
        paths = write_dicom_series(scout, scout_dir, rescale_intercept=-1024, description="Topogram", series_number=99)
        shutil.move(str(paths[0]), folder / "IM9999")
        shutil.rmtree(scout_dir)
        info["scout"] = folder / "IM9999"
    return info


def tilted_direction(degrees: float) -> np.ndarray:
    """An oblique orientation: rotated about the patient's left-right axis by ``degrees``."""
    a = math.radians(degrees)
    rotation = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    return rotation


def write_enhanced(volume: Volume, path: Path, *, frames: range | None = None, temporal: int | None = None,
                   series_uid: str | None = None, study_uid: str | None = None, values=None) -> Path:
    """Write slices of ``volume`` as one *enhanced* CT file: geometry only in the functional groups.

    ``frames`` picks the k slices (default all); ``temporal`` sets FrameContentSequence.TemporalPositionIndex;
    ``values`` replaces the array (same shape). Like Siemens XA exports, the file has no top-level
    ImagePositionPatient, ImageOrientationPatient or PixelSpacing.
    """
    from pydicom.dataset import Dataset, FileDataset, FileMetaDataset
    from pydicom.sequence import Sequence
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    array = np.asarray(volume.array if values is None else values)
    frames = range(array.shape[0]) if frames is None else frames
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.2.1"  # Enhanced CT Image Storage
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = FileDataset(str(path), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID = meta.MediaStorageSOPClassUID
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.StudyInstanceUID = study_uid or generate_uid()
    ds.SeriesInstanceUID = series_uid or generate_uid()
    ds.Modality = "CT"
    ds.SeriesDescription = "enhanced"
    ds.InstanceNumber = 1
    ds.Rows, ds.Columns = array.shape[1], array.shape[2]
    ds.NumberOfFrames = len(frames)
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.BitsAllocated = ds.BitsStored = 16
    ds.HighBit = 15
    ds.PixelRepresentation = 1
    shared = Dataset()
    measures = Dataset()
    measures.PixelSpacing = [f"{volume.spacing[1]:.6f}", f"{volume.spacing[0]:.6f}"]
    measures.SliceThickness = f"{volume.spacing[2]:.6f}"
    orientation = Dataset()
    orientation.ImageOrientationPatient = [f"{v:.6f}" for v in np.concatenate([volume.direction[:, 0], volume.direction[:, 1]])]
    transform = Dataset()
    transform.RescaleSlope, transform.RescaleIntercept, transform.RescaleType = "1", "0", "HU"
    shared.PixelMeasuresSequence = Sequence([measures])
    shared.PlaneOrientationSequence = Sequence([orientation])
    shared.PixelValueTransformationSequence = Sequence([transform])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    per_frame = []
    for k in frames:
        item = Dataset()
        position = Dataset()
        position.ImagePositionPatient = [f"{v:.6f}" for v in volume.index_to_world((0, 0, k))]
        item.PlanePositionSequence = Sequence([position])
        if temporal is not None:
            content = Dataset()
            content.TemporalPositionIndex = temporal
            item.FrameContentSequence = Sequence([content])
        per_frame.append(item)
    ds.PerFrameFunctionalGroupsSequence = Sequence(per_frame)
    ds.PixelData = np.ascontiguousarray(array[list(frames)].astype(np.int16)).tobytes()
    ds.save_as(path, enforce_file_format=True)
    return path


def patch_element(path: Path, tag: int, value: bytes) -> None:
    """Replace the value of a short explicit-VR little-endian element in the file's bytes, as damage would."""
    import struct

    data = path.read_bytes()
    key = struct.pack("<HH", tag >> 16, tag & 0xFFFF)
    at = data.index(key, 132)
    length = struct.unpack("<H", data[at + 6:at + 8])[0]
    value = value + b" " * (len(value) % 2)
    path.write_bytes(data[:at + 6] + struct.pack("<H", len(value)) + value + data[at + 8 + length:])


@contextlib.contextmanager
def lenient_pydicom():
    """Let pydicom write invalid values (as damaged files hold them)."""
    from pydicom import config

    saved = config.settings.writing_validation_mode, config.settings.reading_validation_mode
    config.settings.writing_validation_mode = config.settings.reading_validation_mode = config.IGNORE
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        config.settings.writing_validation_mode, config.settings.reading_validation_mode = saved
