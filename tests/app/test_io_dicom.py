"""DICOM reading on real files (pydicom's test data) and on scanner-like series written by pydicom."""

from __future__ import annotations

import math
import shutil
import warnings

import numpy as np
import pydicom
import pytest
from pydicom.data import get_testdata_file

from app.io import (
    CorruptFileError,
    DicomSeriesError,
    MissingDecoderError,
    load_volume,
    write_dicom_series,
)
from app.io.dicom import decode_pixels, scan_folder
from app.volume import Volume

from .dicom_helpers import small_ct, tilted_direction, write_scanner_folder


def test_scanner_folder_geometry_and_hu(tmp_path):
    volume = small_ct()
    info = write_scanner_folder(volume, tmp_path / "series")
    loaded = load_volume(tmp_path / "series")

    assert loaded.dimensions == volume.dimensions
    assert np.allclose(loaded.spacing, volume.spacing)
    assert np.allclose(loaded.origin, volume.origin, atol=1e-5)
    assert np.allclose(loaded.direction, volume.direction)
    assert loaded.modality == "CT" and loaded.units == "HU"
    # Stored as unsigned with intercept -1024; read back in HU, slice order by position, not by file name.
    assert loaded.array.dtype == np.int16
    np.testing.assert_array_equal(loaded.array, volume.array)
    assert loaded.value_range == volume.value_range
    others = loaded.metadata["other_series"]
    assert len(others) == 1 and others[0]["description"] == "Topogram" and others[0]["slices"] == 1
    assert info["names"] != sorted(info["names"])  # the folder really was shuffled


def test_slices_sorted_by_position_not_instance_number(tmp_path):
    volume = small_ct()
    paths = write_dicom_series(volume, tmp_path / "s", rescale_intercept=-1024)
    # Scramble InstanceNumber: a reader that sorted by it would mix the slices.
    rng = np.random.default_rng(3)
    for path, number in zip(paths, rng.permutation(len(paths)) + 1):
        ds = pydicom.dcmread(path)
        ds.InstanceNumber = int(number)
        ds.save_as(path)
    np.testing.assert_array_equal(load_volume(tmp_path / "s").array, volume.array)


def test_oblique_orientation_is_kept(tmp_path):
    volume = small_ct()
    volume.direction = tilted_direction(20.0)
    write_dicom_series(volume, tmp_path / "oblique", rescale_intercept=-1024)
    loaded = load_volume(tmp_path / "oblique")
    assert np.allclose(loaded.direction, volume.direction, atol=1e-6)
    assert np.allclose(loaded.spacing, volume.spacing, atol=1e-6)
    assert np.allclose(loaded.world_corners, volume.world_corners, atol=1e-4)
    np.testing.assert_array_equal(loaded.array, volume.array)


def test_truncated_and_stray_files_are_named(tmp_path):
    volume = small_ct()
    folder = tmp_path / "series"
    paths = write_dicom_series(volume, folder, rescale_intercept=-1024)
    truncated = paths[0]  # an end slice: the rest still forms a regular stack
    data = truncated.read_bytes()
    truncated.write_bytes(data[: len(data) - 500])
    (folder / "notes.txt").write_text("scanned on Tuesday")
    (folder / "Thumbs.db").write_bytes(b"\x00\x01garbage" * 10)

    loaded = load_volume(folder)
    text = "\n".join(loaded.metadata["warnings"])
    assert f"{truncated}: skipped" in text and "truncated" in text
    assert "notes.txt: skipped, not a DICOM file" in text
    assert "Thumbs.db: skipped, not a DICOM file" in text
    assert loaded.dimensions == (volume.dimensions[0], volume.dimensions[1], volume.dimensions[2] - 1)
    np.testing.assert_array_equal(loaded.array, volume.array[1:])


def test_missing_slice_resampled_or_refused(tmp_path):
    volume = small_ct()
    paths = write_dicom_series(volume, tmp_path / "gap", rescale_intercept=-1024)
    paths[5].unlink()
    loaded = load_volume(tmp_path / "gap")
    text = "\n".join(loaded.metadata["warnings"])
    assert "1 slice(s) missing" in text and "resampled" in text
    assert loaded.dimensions == volume.dimensions
    # The missing slice is filled by linear interpolation of its neighbours.
    expected = 0.5 * (volume.array[4].astype(float) + volume.array[6].astype(float))
    np.testing.assert_allclose(loaded.array[5], np.rint(expected), atol=1)
    np.testing.assert_array_equal(loaded.array[:5], volume.array[:5])

    with pytest.raises(DicomSeriesError, match=r"1 slice\(s\) missing"):
        load_volume(tmp_path / "gap", irregular="error")


def test_irregular_spacing_detected(tmp_path):
    volume = small_ct()
    paths = write_dicom_series(volume, tmp_path / "uneven", rescale_intercept=-1024)
    ds = pydicom.dcmread(paths[7])
    position = [float(v) for v in ds.ImagePositionPatient]
    position[2] += 1.1  # 1.1 mm out of place
    ds.ImagePositionPatient = position
    ds.save_as(paths[7])
    with pytest.raises(DicomSeriesError, match="irregular slice spacing"):
        load_volume(tmp_path / "uneven", irregular="error")
    assert any("irregular slice spacing" in w for w in load_volume(tmp_path / "uneven").metadata["warnings"])


def test_gantry_tilt_detected_and_corrected(tmp_path):
    # A vertical rod with a smooth (Gaussian) profile, scanned with the gantry tilted: each slice's position drifts
    # along y, so in the images the rod drifts the other way.
    nz, ny, nx = 10, 32, 32
    spacing = (1.0, 1.0, 2.0)
    tilt = math.radians(12.0)
    drift = spacing[2] * math.tan(tilt)  # mm of y drift per slice
    rod = np.full((nz, ny, nx), -1000, dtype=np.int16)
    yy, xx = np.mgrid[:ny, :nx]
    for k in range(nz):
        # In the tilted slice k the rod appears shifted by -drift*k (the slice itself moved by +drift*k).
        centre_y = 16 - drift * k / spacing[1]
        rod[k] = np.rint(-1000 + 2000 * np.exp(-((yy - centre_y) ** 2 + (xx - 16) ** 2) / (2 * 2.5**2)))
    flat = Volume(rod, spacing=spacing, modality="CT", units="HU")
    paths = write_dicom_series(flat, tmp_path / "tilt", rescale_intercept=-1024)
    for k, path in enumerate(paths):
        ds = pydicom.dcmread(path)
        ds.ImagePositionPatient = [0.0, drift * k, spacing[2] * k]
        ds.save_as(path)
    loaded = load_volume(tmp_path / "tilt")
    assert abs(loaded.metadata["gantry_tilt_deg"] - 12.0) < 0.01
    assert any("gantry tilt of 12.00 degrees" in w for w in loaded.metadata["warnings"])
    # The grid grows by the total drift (9 slices x 0.425 mm = 3.83 pixels -> 4 rows), so no pixel is dropped.
    assert loaded.dimensions == (nx, ny + 4, nz)

    def centroid_rows(image):
        weight = image.astype(float) + 1000
        rows = np.arange(image.shape[0])[:, None]
        return float((weight * rows).sum() / weight.sum())

    # After correction the rod is vertical: its centroid no longer moves from slice to slice ...
    centroids = [centroid_rows(loaded.array[k]) for k in range(nz)]
    assert np.ptp(centroids) < 0.05  # pixels
    assert np.ptp([centroid_rows(rod[k]) for k in range(nz)]) > 3.5
    # ... it sits where the scanner put it in the patient (world y = 16 mm) ...
    world = loaded.index_to_world((16, centroids[0], 0))
    assert world[1] == pytest.approx(16.0, abs=0.05)
    # ... and every slice keeps all of its signal (linear interpolation conserves the sum when nothing is cut).
    for k in range(nz):
        assert (loaded.array[k].astype(float) + 1000).sum() == pytest.approx((rod[k].astype(float) + 1000).sum(), rel=1e-4)


def test_gantry_tilt_keeps_pixels_at_the_edge(tmp_path):
    # Bright pixels on the rows a tilt correction shifts out of the original field of view must survive.
    nz, ny, nx = 6, 20, 16
    spacing = (1.0, 1.0, 2.0)
    drift = spacing[2] * math.tan(math.radians(20.0))
    stack = np.full((nz, ny, nx), -1000, dtype=np.int16)
    stack[:, 0, :] = 1000  # first row of every slice
    stack[:, -1, :] = 500  # last row
    flat = Volume(stack, spacing=spacing, modality="CT", units="HU")
    paths = write_dicom_series(flat, tmp_path / "edge", rescale_intercept=-1024)
    for k, path in enumerate(paths):
        ds = pydicom.dcmread(path)
        ds.ImagePositionPatient = [0.0, -drift * k, spacing[2] * k]
        ds.save_as(path)
    loaded = load_volume(tmp_path / "edge")
    assert loaded.dimensions[1] > ny
    for k in range(nz):
        assert (loaded.array[k].astype(float) + 1000).sum() == pytest.approx((stack[k].astype(float) + 1000).sum(), rel=1e-4)


def test_several_series_choose_and_list(tmp_path):
    folder = tmp_path / "two"
    big = small_ct()
    write_dicom_series(big, folder / "a", rescale_intercept=-1024, description="big")
    small = small_ct(shape=(6, 20, 20))
    uid = "1.2.826.0.1.3680043.8.498.424242"
    write_dicom_series(small, folder / "b", rescale_intercept=-1024, description="small", series_uid=uid)
    default = load_volume(folder)
    assert default.dimensions == big.dimensions
    assert [s["description"] for s in default.metadata["other_series"]] == ["small"]
    chosen = load_volume(folder, series_uid=uid)
    assert chosen.dimensions == small.dimensions
    with pytest.raises(DicomSeriesError, match="no series with UID 1.2.3"):
        load_volume(folder, series_uid="1.2.3")


def test_echoes_sharing_positions(tmp_path):
    volume = small_ct(shape=(5, 16, 16))
    uid = "1.2.826.0.1.3680043.8.498.777"
    paths_1 = write_dicom_series(volume, tmp_path / "e" / "1", series_uid=uid, rescale_intercept=-1024)
    paths_2 = write_dicom_series(volume.with_array(volume.array // 2), tmp_path / "e" / "2", series_uid=uid,
                                 rescale_intercept=-1024)
    for echo, paths in ((1, paths_1), (2, paths_2)):
        for path in paths:
            ds = pydicom.dcmread(path)
            ds.EchoNumbers = echo
            ds.save_as(path)
    loaded = load_volume(tmp_path / "e")
    assert any("echo numbers 1, 2" in w for w in loaded.metadata["warnings"])
    np.testing.assert_array_equal(loaded.array, volume.array)


def test_single_slice_is_refused(tmp_path):
    folder = tmp_path / "one"
    folder.mkdir()
    shutil.copy(get_testdata_file("CT_small.dcm"), folder / "CT_small.dcm")
    with pytest.raises(DicomSeriesError, match="single slice"):
        load_volume(folder)


def test_empty_and_non_dicom_folders(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(DicomSeriesError, match="contains no files"):
        load_volume(tmp_path / "empty")
    (tmp_path / "text").mkdir()
    (tmp_path / "text" / "a.txt").write_text("hello")
    with pytest.raises(DicomSeriesError, match="no DICOM images found"):
        load_volume(tmp_path / "text")


@pytest.mark.parametrize("name", ["MR_small_RLE.dcm", "MR_small_jpeg_ls_lossless.dcm", "MR_small_jp2klossless.dcm",
                                  "MR_small_bigendian.dcm", "MR_small_implicit.dcm"])
def test_real_compressed_and_big_endian_files_decode_like_the_reference(name):
    reference, _ = decode_pixels(get_testdata_file("MR_small.dcm"))
    pixels, _ = decode_pixels(get_testdata_file(name))
    np.testing.assert_array_equal(pixels, reference)


def test_real_truncated_file_is_reported():
    with pytest.raises(CorruptFileError, match="MR_truncated.dcm: the pixel data is damaged or truncated"):
        decode_pixels(get_testdata_file("MR_truncated.dcm"))


def test_compressed_series(tmp_path):
    from pydicom.uid import RLELossless

    volume = small_ct(shape=(6, 24, 20))
    for path in write_dicom_series(volume, tmp_path / "rle", rescale_intercept=-1024):
        ds = pydicom.dcmread(path)
        ds.compress(RLELossless)
        ds.save_as(path)
    loaded = load_volume(tmp_path / "rle")
    np.testing.assert_array_equal(loaded.array, volume.array)


def test_missing_decoder_names_the_syntax(tmp_path):
    volume = small_ct(shape=(3, 16, 16))
    paths = write_dicom_series(volume, tmp_path / "jxl", rescale_intercept=-1024)
    for path in paths:
        ds = pydicom.dcmread(path)
        # JPEG 2000 Part 2 multi-component: a syntax pydicom knows but no plugin decodes; the bytes need not be valid.
        ds.file_meta.TransferSyntaxUID = pydicom.uid.JPEG2000MCLossless
        ds.PixelData = pydicom.encaps.encapsulate([b"\xff\x0a" + bytes(64)])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds.save_as(path, enforce_file_format=False)
    with pytest.raises(MissingDecoderError, match=r"compressed as 'JPEG 2000 Part 2 .*1\.2\.840\.10008\.1\.2\.4\.92.*convert the series"):
        load_volume(tmp_path / "jxl")


def test_real_multiframe_rtdose():
    volume = load_volume(get_testdata_file("rtdose.dcm"))
    assert volume.dimensions == (10, 10, 15)
    assert volume.metadata["source_format"] == "DICOM multi-frame"
    assert volume.units == "Gy"
    ds = pydicom.dcmread(get_testdata_file("rtdose.dcm"))
    offsets = np.asarray(ds.GridFrameOffsetVector, dtype=float)
    assert math.isclose(volume.spacing[2], abs(np.median(np.diff(offsets))), rel_tol=1e-6)
    expected = ds.pixel_array.astype(float) * float(ds.DoseGridScaling)
    order = np.argsort(offsets)
    np.testing.assert_allclose(volume.array, expected[order], rtol=1e-6)


def test_scan_reports_non_image_objects(tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    shutil.copy(get_testdata_file("rtplan.dcm"), folder / "plan.dcm")
    scan = scan_folder(folder)
    assert scan.series == []
    assert scan.skipped and "no image in this object" in scan.skipped[0][1]


def test_images_without_patient_geometry_are_refused(tmp_path):
    volume = small_ct(shape=(3, 16, 16))
    for path in write_dicom_series(volume, tmp_path / "sc", rescale_intercept=-1024):
        ds = pydicom.dcmread(path)
        del ds.ImagePositionPatient
        ds.save_as(path)
    with pytest.raises(DicomSeriesError, match="lacks ImagePositionPatient.*secondary capture"):
        load_volume(tmp_path / "sc")


def test_slices_sharing_a_position_without_echoes_are_refused(tmp_path):
    volume = small_ct(shape=(4, 16, 16))
    uid = "1.2.826.0.1.3680043.8.498.31337"
    write_dicom_series(volume, tmp_path / "dup" / "a", series_uid=uid, rescale_intercept=-1024)
    write_dicom_series(volume, tmp_path / "dup" / "b", series_uid=uid, rescale_intercept=-1024,
                       file_names=[f"copy_{k}.dcm" for k in range(4)])
    with pytest.raises(DicomSeriesError, match="several slices share the same position"):
        load_volume(tmp_path / "dup")


def test_duplicate_files_are_named_and_skipped(tmp_path):
    volume = small_ct(shape=(4, 16, 16))
    paths = write_dicom_series(volume, tmp_path / "copy", rescale_intercept=-1024)
    shutil.copy(paths[1], tmp_path / "copy" / "again.dcm")
    loaded = load_volume(tmp_path / "copy")
    assert any("again.dcm: skipped, duplicate of" in w or "slice_0001.dcm: skipped, duplicate of" in w
               for w in loaded.metadata["warnings"])
    np.testing.assert_array_equal(loaded.array, volume.array)
