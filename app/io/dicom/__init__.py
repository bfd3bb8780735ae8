"""DICOM series, multi-frame and MOSAIC readers (pydicom), and a series writer for tests and demos.

=================  ==============================================================================
module             what it does
=================  ==============================================================================
``scan``           headers without pixels, folder scan, one entry per 2D image, grouping, choice
``pixels``         decoding (compressed syntaxes through pydicom's plugins), units, stored type
``stack``          duplicates, several volumes per series, order, pixels, gantry tilt, gaps
``multiframe``     enhanced files (frames from functional groups), legacy multi-frame files
``mosaic``         Siemens MOSAIC files un-tiled into slices (CSA header)
``series``         :func:`read_dicom_series`, :func:`read_dicom_file`: the steps above in order
``write``          :func:`write_dicom_series` (single-frame series, uncompressed)
=================  ==============================================================================

A file that cannot be read (not DICOM, truncated, a malformed element) is skipped with a warning naming it and
never blocks the rest of a folder; pydicom's own warnings are collected into the volume's warnings.
"""

from __future__ import annotations

from .headers import SliceHeader, read_header
from .multiframe import read_multiframe
from .pixels import decode_pixels
from .scan import FolderScan, SeriesInfo, is_dicom_file, list_series, scan_folder
from .series import read_dicom_file, read_dicom_series
from .stack import MAX_INTERPOLATED_SLICES
from .write import write_dicom_series

__all__ = [
    "MAX_INTERPOLATED_SLICES", "FolderScan", "SeriesInfo", "SliceHeader", "decode_pixels", "is_dicom_file",
    "list_series", "read_dicom_file", "read_dicom_series", "read_header", "read_multiframe", "scan_folder",
    "write_dicom_series",
]
