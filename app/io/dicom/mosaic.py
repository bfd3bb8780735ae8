"""Siemens MOSAIC images: one file holding every slice of a volume as tiles of one large 2D image.

A MOSAIC file (``ImageType`` contains ``MOSAIC``) stores ``NumberOfImagesInMosaic`` slices (from the Siemens CSA
image header, element (0029,1010)) as tiles in a square grid of ``ceil(sqrt(n))`` tiles per side; each tile is
``Rows // side`` by ``Columns // side`` pixels (integer division: pixels beyond the last whole tile are padding).
The file's ImagePositionPatient is the corner of the whole mosaic, not of the first slice; the first slice's
corner is found by moving half the difference between mosaic and tile size along the row and column directions,
and slice ``k`` lies ``k`` slice spacings along the CSA ``SliceNormalVector``. This is the method of nibabel's
``MosaicWrapper`` and of dcm2niix (Li et al. 2016, "The first step for neuroimaging data analysis: DICOM to NIfTI
conversion", J Neurosci Methods 264:47-56).

Each file is one volume (a time point or a diffusion direction); several files of a series are several volumes,
which :mod:`.stack` lists and chooses from.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .headers import ElementError, SliceHeader, number


@dataclass(frozen=True)
class MosaicLayout:
    """Where one slice sits in its mosaic: tile ``index`` of ``count`` in a grid ``side`` tiles wide."""

    index: int
    count: int
    side: int
    tile_rows: int
    tile_columns: int

    def tile(self, pixels: np.ndarray) -> np.ndarray:
        """The slice's pixels from the whole mosaic image ``(Rows, Columns)``."""
        row, column = divmod(self.index, self.side)
        return pixels[row * self.tile_rows:(row + 1) * self.tile_rows,
                      column * self.tile_columns:(column + 1) * self.tile_columns]


def _csa_image_header(dataset):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # nibabel.nicom announces itself as experimental
        from nibabel.nicom import csareader

        return csareader, csareader.get_csa_header(dataset, "image")


def mosaic_tiles(header: SliceHeader, dataset) -> list[SliceHeader] | None:
    """One header per slice of a MOSAIC file, or None when the file is not a MOSAIC."""
    if "MOSAIC" not in header.image_type.upper().split("\\"):
        return None
    try:
        csareader, csa = _csa_image_header(dataset)
    except Exception as exc:  # nibabel's CSA reader raises its own errors for damaged headers
        raise ElementError(f"the Siemens CSA image header (0029,1010) is damaged ({exc})") from exc
    if not csa:
        raise ElementError("the MOSAIC image has no Siemens CSA image header (0029,1010) to un-tile it")
    count = csareader.get_n_mosaic(csa)
    if count is None or int(count) < 1:
        raise ElementError("the CSA header has no NumberOfImagesInMosaic")
    count = int(count)
    side = math.ceil(math.sqrt(count))
    tile_rows, tile_columns = header.rows // side, header.columns // side
    if tile_rows < 1 or tile_columns < 1:
        raise ElementError(f"NumberOfImagesInMosaic {count} does not fit a {header.columns}x{header.rows} image")
    if header.position is None or header.orientation is None or header.pixel_spacing is None:
        return [header]  # cannot be placed; the stacker refuses it with its usual message
    row_cosine, column_cosine = header.orientation[:3], header.orientation[3:]
    normal = csareader.get_slice_normal(csa)
    if normal is None or not np.all(np.isfinite(normal)) or np.linalg.norm(normal) < 0.5:
        normal = np.cross(row_cosine, column_cosine)
    normal = np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
    spacing = number(dataset, "SpacingBetweenSlices", None, positive=True) or \
        number(dataset, "SliceThickness", None, positive=True)
    if spacing is None:
        raise ElementError("the MOSAIC image has neither SpacingBetweenSlices nor SliceThickness")
    # The stored position is that of the whole mosaic's corner; move to the first tile's corner.
    row_spacing, column_spacing = header.pixel_spacing
    shift_rows = (header.rows - header.rows / side) / 2
    shift_columns = (header.columns - header.columns / side) / 2
    first = header.position + column_cosine * row_spacing * shift_rows + row_cosine * column_spacing * shift_columns
    tiles = []
    for index in range(count):
        tiles.append(replace(
            header, rows=tile_rows, columns=tile_columns, position=first + index * spacing * normal,
            frame=index, volume_key=("file", str(header.path)),
            mosaic=MosaicLayout(index, count, side, tile_rows, tile_columns),
        ))
    return tiles
