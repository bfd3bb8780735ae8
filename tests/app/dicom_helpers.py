"""Builders of scanner-like DICOM folders for the reader tests (pydicom writes real files)."""

from __future__ import annotations

import math
import shutil
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
