"""DICOM folders as scanners write them: damaged neighbours, MOSAIC, several volumes, enhanced files, gaps."""

from __future__ import annotations

import gzip
import shutil
import warnings
from pathlib import Path

import nibabel
import numpy as np
import pydicom
import pytest
from pydicom.data import get_testdata_file
from pydicom.uid import generate_uid

from app.io import CorruptFileError, DicomSeriesError, list_series, load_volume, write_dicom_series
from app.io.dicom import MAX_INTERPOLATED_SLICES, scan_folder

from ..dicom_helpers import lenient_pydicom, patch_element, small_ct, write_enhanced

NICOM = Path(nibabel.__file__).parent / "nicom" / "tests" / "data"


# ----------------------------------------------------------------------------------------------------------------
# One bad file never blocks a folder
# ----------------------------------------------------------------------------------------------------------------
def test_bad_vr_file_next_to_a_good_series(tmp_path, recwarn):
    volume = small_ct(shape=(5, 16, 16))
    write_dicom_series(volume, tmp_path / "s", rescale_intercept=-1024)
    shutil.copy(get_testdata_file("badVR.dcm"), tmp_path / "s" / "badVR.dcm")
    loaded = load_volume(tmp_path / "s")
    np.testing.assert_array_equal(loaded.array, volume.array)
    text = "\n".join(loaded.metadata["warnings"])
    assert "badVR.dcm: skipped, NumberOfFrames '1A' is not a number" in text
    # pydicom's own warning ("Invalid value for VR IS") is ours now, not on standard error.
    assert "pydicom: Invalid value for VR IS: '1A'" in text
    assert not [w for w in recwarn.list if "pydicom" in str(w.filename) or "VR" in str(w.message)]


@pytest.mark.parametrize("element, value, expected", [
    ("RescaleSlope", "x", "RescaleSlope 'x' is not a number"),
    ("RescaleSlope", "0", "RescaleSlope is 0"),
    ("RescaleIntercept", ["1", "2"], "RescaleIntercept holds 2 values"),
    ("Rows", None, "Rows"),
    ("ImagePositionPatient", ["1", "a", "3"], "ImagePositionPatient must hold 3 finite numbers"),
])
def test_malformed_elements_name_the_file_and_element(tmp_path, element, value, expected):
    volume = small_ct(shape=(6, 16, 16))
    paths = write_dicom_series(volume, tmp_path / "s", rescale_intercept=-1024)
    if element == "Rows":
        with lenient_pydicom():
            ds = pydicom.dcmread(paths[0])
            ds[element].value = [16, 16]
            ds.save_as(paths[0])
    else:
        text = value if isinstance(value, str) else "\\".join(value)
        patch_element(paths[0], pydicom.datadict.tag_for_keyword(element), text.encode())
    loaded = load_volume(tmp_path / "s")  # an end slice: the rest still forms a regular stack
    assert loaded.dimensions[2] == 5
    skipped = [w for w in loaded.metadata["warnings"] if "skipped" in w]
    assert len(skipped) == 1 and str(paths[0]) in skipped[0] and expected in skipped[0], skipped


def test_fifo_in_a_dicom_folder_is_skipped_not_read(tmp_path):
    import os

    volume = small_ct(shape=(4, 16, 16))
    write_dicom_series(volume, tmp_path / "s", rescale_intercept=-1024)
    os.mkfifo(tmp_path / "s" / "pipe")
    loaded = load_volume(tmp_path / "s")
    assert any("pipe: skipped, not a regular file" in w for w in loaded.metadata["warnings"])


def test_only_the_chosen_series_pixels_are_read(tmp_path):
    big = small_ct(shape=(6, 16, 16))
    write_dicom_series(big, tmp_path / "f" / "a", rescale_intercept=-1024)
    paths = write_dicom_series(small_ct(shape=(3, 12, 12)), tmp_path / "f" / "b", rescale_intercept=-1024)
    data = paths[1].read_bytes()
    paths[1].write_bytes(data[:-100])  # damaged pixels in the series not chosen
    loaded = load_volume(tmp_path / "f")
    assert loaded.dimensions == big.dimensions
    assert not any("slice_0001" in w and "b" in w for w in loaded.metadata["warnings"])


# ----------------------------------------------------------------------------------------------------------------
# Siemens MOSAIC (nibabel's test files)
# ----------------------------------------------------------------------------------------------------------------
def test_mosaic_files_are_untiled(tmp_path):
    for name in ("0.dcm", "1.dcm"):
        shutil.copy(NICOM / name, tmp_path / name)
    volume = load_volume(tmp_path)
    # 48 slices of 36x36 tiled 7x7 in a 256x256 image (dcm2niix gives the same): not 256x256x2 with a "tilt".
    assert volume.dimensions == (36, 36, 48)
    assert volume.metadata["source_format"] == "DICOM MOSAIC"
    assert volume.spacing == pytest.approx((1.796875, 1.796875, 3.0))
    assert volume.metadata["gantry_tilt_deg"] == 0
    assert [v["file"] for v in volume.metadata["volumes"]] == ["0.dcm", "1.dcm"]
    assert any("holds 2 volumes (files 0.dcm, 1.dcm); loaded file 0.dcm (48 slices)" in w
               for w in volume.metadata["warnings"])
    second = load_volume(tmp_path, volume_index=1)
    assert second.dimensions == (36, 36, 48)
    # 1.dcm lies 3 mm further along z.
    assert np.subtract(second.origin, volume.origin) == pytest.approx((0, 0, 3.0), abs=1e-3)
    assert list_series(tmp_path)[0]["volumes"] == 2
    with pytest.raises(DicomSeriesError, match="volume 2 was asked for, but the series holds 2"):
        load_volume(tmp_path, volume_index=2)


def test_mosaic_matches_nibabel(tmp_path):
    from nibabel.nicom import dicomwrappers

    for name in ("siemens_dwi_0.dcm.gz", "siemens_dwi_1000.dcm.gz"):
        (tmp_path / name[:-3]).write_bytes(gzip.decompress((NICOM / name).read_bytes()))
    for index, name in enumerate(("siemens_dwi_0.dcm", "siemens_dwi_1000.dcm")):
        volume = load_volume(tmp_path, volume_index=index)
        assert volume.dimensions == (128, 128, 48)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            wrapper = dicomwrappers.wrapper_from_data(pydicom.dcmread(tmp_path / name))
            data = wrapper.get_data()  # (rows, columns, slices)
        np.testing.assert_array_equal(volume.array, data.transpose(2, 0, 1))
        # nibabel's affine maps (row, column, slice) to LPS; ours maps (column, row, slice).
        for rcs in ([0, 0, 0], [127, 5, 47], [60, 100, 20]):
            expected = wrapper.affine @ np.array(rcs + [1.0])
            assert volume.index_to_world((rcs[1], rcs[0], rcs[2])) == pytest.approx(expected[:3], abs=1e-3)


def test_mosaic_without_pixels_names_the_file():
    with pytest.raises(CorruptFileError, match="csa_slice_norm.dcm: the file has no pixel data"):
        load_volume(NICOM / "csa_slice_norm.dcm")


# ----------------------------------------------------------------------------------------------------------------
# Several volumes in one series
# ----------------------------------------------------------------------------------------------------------------
def _time_series(tmp_path, count: int, *, instance_order: bool):
    """A GE-style series: ``count`` volumes at the same positions, told apart only by InstanceNumber."""
    volume = small_ct(shape=(5, 16, 16))
    uid = generate_uid()
    folder = tmp_path / "fmri"
    for t in range(count):
        frames = write_dicom_series(volume.with_array(volume.array + 10 * t), folder / f"t{t}", series_uid=uid,
                                    rescale_intercept=-1024, file_names=[f"t{t}_{k}.dcm" for k in range(5)])
        for k, path in enumerate(frames):
            ds = pydicom.dcmread(path)
            ds.InstanceNumber = t * 5 + k + 1 if instance_order else 1
            ds.save_as(path)
    return folder, volume


def test_volumes_told_apart_by_acquisition_order(tmp_path):
    folder, volume = _time_series(tmp_path, 3, instance_order=True)
    loaded = load_volume(folder)
    np.testing.assert_array_equal(loaded.array, volume.array)
    assert [v["acquisition order"] for v in loaded.metadata["volumes"]] == ["1", "2", "3"]
    assert any("holds 3 volumes" in w for w in loaded.metadata["warnings"])
    np.testing.assert_array_equal(load_volume(folder, volume_index=2).array, volume.array + 20)


def test_volumes_that_cannot_be_told_apart_are_refused(tmp_path):
    folder, _ = _time_series(tmp_path, 2, instance_order=False)
    with pytest.raises(DicomSeriesError, match="several slices share the same position"):
        load_volume(folder)


def test_temporal_positions(tmp_path):
    volume = small_ct(shape=(4, 16, 16))
    uid = generate_uid()
    for t in (1, 2):
        for path in write_dicom_series(volume.with_array(volume.array + t), tmp_path / "s" / str(t), series_uid=uid,
                                       rescale_intercept=-1024):
            ds = pydicom.dcmread(path)
            ds.TemporalPositionIdentifier = t
            ds.save_as(path)
    loaded = load_volume(tmp_path / "s", volume_index=1)
    np.testing.assert_array_equal(loaded.array, volume.array + 2)
    assert loaded.metadata["volume_index"] == 1


# ----------------------------------------------------------------------------------------------------------------
# Enhanced multi-frame files
# ----------------------------------------------------------------------------------------------------------------
def test_folder_of_enhanced_single_frame_files(tmp_path):
    # Siemens XA style: one enhanced file per slice, geometry only in the functional groups.
    volume = small_ct(shape=(6, 20, 18))
    uid, study = generate_uid(), generate_uid()
    (tmp_path / "xa").mkdir()
    for k in (3, 0, 5, 1, 4, 2):
        write_enhanced(volume, tmp_path / "xa" / f"IM{k}", frames=range(k, k + 1), series_uid=uid, study_uid=study)
    loaded = load_volume(tmp_path / "xa")
    np.testing.assert_array_equal(loaded.array, volume.array)
    assert np.allclose(loaded.origin, volume.origin) and np.allclose(loaded.spacing, volume.spacing)
    assert loaded.metadata["source_format"] == "DICOM multi-frame"


def test_folder_of_enhanced_volumes(tmp_path):
    volume = small_ct(shape=(5, 16, 16))
    uid, study = generate_uid(), generate_uid()
    (tmp_path / "t").mkdir()
    for t in (1, 2):
        write_enhanced(volume, tmp_path / "t" / f"T{t}.dcm", series_uid=uid, study_uid=study, temporal=t,
                       values=volume.array + 100 * t)
    first = load_volume(tmp_path / "t")
    np.testing.assert_array_equal(first.array, volume.array + 100)
    assert [v["temporal position"] for v in first.metadata["volumes"]] == ["1", "2"]
    single = load_volume(tmp_path / "t" / "T2.dcm")  # one file is a volume by itself
    np.testing.assert_array_equal(single.array, volume.array + 200)


def test_real_enhanced_philips_file(tmp_path):
    path = tmp_path / "mprage.dcm"
    path.write_bytes(gzip.decompress((NICOM / "philips_mprage.dcm.gz").read_bytes()))
    volume = load_volume(path)
    assert volume.dimensions == (256, 256, 176)
    assert volume.spacing == pytest.approx((1.0, 1.0, 1.0), abs=1e-4)


# ----------------------------------------------------------------------------------------------------------------
# Gaps
# ----------------------------------------------------------------------------------------------------------------
def _remove(paths, indices):
    for i in indices:
        paths[i].unlink()


@pytest.mark.parametrize("missing", [1, 2])
def test_small_gaps_are_interpolated_and_counted(tmp_path, missing):
    volume = small_ct(shape=(10, 16, 16))
    paths = write_dicom_series(volume, tmp_path / "g", rescale_intercept=-1024)
    _remove(paths, range(4, 4 + missing))
    loaded = load_volume(tmp_path / "g")
    assert loaded.dimensions == volume.dimensions
    assert loaded.metadata["interpolated_slices"] == missing
    assert any(f"{missing} slice(s) invented by interpolation" in w for w in loaded.metadata["warnings"])
    assert MAX_INTERPOLATED_SLICES == 2


def test_larger_gaps_are_refused_unless_allowed(tmp_path):
    volume = small_ct(shape=(10, 16, 16))
    paths = write_dicom_series(volume, tmp_path / "g", rescale_intercept=-1024)
    _remove(paths, range(3, 6))
    with pytest.raises(DicomSeriesError, match=r"a gap of 12\.0 mm .* 3 consecutive slices invented .*--allow-gaps"):
        load_volume(tmp_path / "g")
    loaded = load_volume(tmp_path / "g", allow_gaps=True)
    assert loaded.metadata["interpolated_slices"] == 3 and loaded.dimensions == volume.dimensions


def test_four_slices_with_a_202_mm_gap(tmp_path):
    volume = small_ct(shape=(4, 16, 16), spacing=(1.0, 1.0, 1.25))
    paths = write_dicom_series(volume, tmp_path / "g", rescale_intercept=-1024)
    ds = pydicom.dcmread(paths[3])
    position = [float(v) for v in ds.ImagePositionPatient]
    position[2] += 202.0 - 1.25
    ds.ImagePositionPatient = position
    ds.save_as(paths[3])
    with pytest.raises(DicomSeriesError) as caught:
        load_volume(tmp_path / "g")
    message = str(caught.value)
    assert "a gap of 202.0 mm" in message and "--allow-gaps" in message and "\n" not in message
    allowed = load_volume(tmp_path / "g", allow_gaps=True)
    # 165 slices at 1.25 mm from 0 to 205 mm; only 3 lie within a quarter spacing of an acquired slice.
    assert allowed.dimensions[2] == 165
    assert allowed.metadata["interpolated_slices"] == 162
    assert any("162 slice(s) invented" in w for w in allowed.metadata["warnings"])


def test_no_gap_reports_zero_invented_slices(tmp_path):
    volume = small_ct(shape=(5, 16, 16))
    write_dicom_series(volume, tmp_path / "s", rescale_intercept=-1024)
    assert load_volume(tmp_path / "s").metadata["interpolated_slices"] == 0


def test_scan_reports_skipped_files(tmp_path):
    volume = small_ct(shape=(3, 16, 16))
    write_dicom_series(volume, tmp_path / "s", rescale_intercept=-1024)
    (tmp_path / "s" / "junk.dcm").write_bytes(b"DICM" * 10)
    scan = scan_folder(tmp_path / "s")
    assert [p.name for p, _ in scan.skipped] == ["junk.dcm"]
