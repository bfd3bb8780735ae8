"""NRRD through pynrrd's header parser: byte skip, line skip, endian, vectors and exact data sizes."""

from __future__ import annotations

import gzip
import os

import nibabel
import nrrd
import numpy as np
import pytest

from app.io import CorruptFileError, UnsupportedFormatError, VolumeReadError, load_volume

HEADER = (
    "NRRD0004\n# Complete NRRD file format specification at:\n# http://teem.sourceforge.net/nrrd/format.html\n"
    "type: short\ndimension: 3\nspace: left-posterior-superior\nsizes: 30 30 30\n{skip}"
    "space directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain domain\nendian: little\n"
    "encoding: {encoding}\nspace origin: (0,0,0)\ndata file: {data}\n"
)


@pytest.fixture
def ball(tmp_path):
    """pynrrd's BallBinary30x30x30 case rebuilt: a 30^3 short ball stored as NIfTI (.nii.gz and .nii)."""
    grid = np.indices((30, 30, 30)) - 14.5
    values = (np.sqrt((grid ** 2).sum(axis=0)) < 10).astype(np.int16) * 100
    values[0, 0, :] = np.arange(30)  # a ramp makes misplacement visible
    image = nibabel.Nifti1Image(values, np.eye(4))
    image.header.set_data_dtype(np.int16)
    nibabel.save(image, tmp_path / "BallBinary30x30x30.nii.gz")
    nibabel.save(image, tmp_path / "BallBinary30x30x30.nii")
    return values


def _nhdr(tmp_path, name, *, skip="byte skip: -1\n", encoding="gzip", data="BallBinary30x30x30.nii.gz"):
    path = tmp_path / name
    path.write_text(HEADER.format(skip=skip, encoding=encoding, data=data))
    return path


def test_byte_skip_minus_one_with_gzip_matches_pynrrd(tmp_path, ball):
    path = _nhdr(tmp_path, "BallBinary30x30x30_byteskip_minus_one_nifti.nhdr")
    reference, _ = nrrd.read(str(path), index_order="C")
    volume = load_volume(path)
    assert int(volume.array.astype(np.int64).sum()) == int(reference.astype(np.int64).sum())
    np.testing.assert_array_equal(volume.array, reference)
    np.testing.assert_array_equal(volume.array, ball.transpose(2, 1, 0))  # NIfTI is x-fastest like NRRD


def test_byte_skip_minus_one_with_raw_data(tmp_path, ball):
    path = _nhdr(tmp_path, "raw.nhdr", encoding="raw", data="BallBinary30x30x30.nii")
    np.testing.assert_array_equal(load_volume(path).array, ball.transpose(2, 1, 0))


def test_without_the_byte_skip_the_extra_header_bytes_are_refused(tmp_path, ball):
    # pynrrd's BallBinary30x30x30_nifti.nhdr has "# byte skip: -1" commented out: the 352 header bytes of the
    # NIfTI file become data, 176 voxels out of place. That is too much data, never a volume.
    path = _nhdr(tmp_path, "BallBinary30x30x30_nifti.nhdr", skip="# byte skip: -1\n")
    with pytest.raises(CorruptFileError, match="BallBinary30x30x30.nii.gz: the gzip data inflates to more than the 54000"):
        load_volume(path)


def test_attached_twin_agrees(tmp_path, ball):
    nrrd.write(str(tmp_path / "twin.nrrd"), ball.transpose(2, 1, 0).copy(), index_order="C",
               header={"space": "left-posterior-superior", "space directions": np.eye(3), "space origin": [0, 0, 0],
                       "encoding": "gzip"})
    np.testing.assert_array_equal(load_volume(tmp_path / "twin.nrrd").array, ball.transpose(2, 1, 0))


def test_positive_byte_skip_and_line_skip(tmp_path):
    values = np.arange(4 * 5 * 6, dtype="<u2").reshape(6, 5, 4)
    (tmp_path / "data.raw").write_bytes(b"first line\nsecond line\nXYZ" + values.tobytes())
    header = ("NRRD0004\ntype: ushort\ndimension: 3\nsizes: 4 5 6\nspacings: 1 1 2\nendian: little\nencoding: raw\n"
              "line skip: 2\nbyte skip: 3\ndata file: data.raw\n")
    (tmp_path / "skip.nhdr").write_text(header)
    volume = load_volume(tmp_path / "skip.nhdr")
    np.testing.assert_array_equal(volume.array, values)
    assert volume.spacing == (1.0, 1.0, 2.0)
    payload = gzip.compress(b"\0" * 10 + values.tobytes())
    (tmp_path / "data.gz").write_bytes(b"a\nb\n" + payload)
    (tmp_path / "gz.nhdr").write_text(header.replace("encoding: raw", "encoding: gzip").replace("byte skip: 3", "byte skip: 10")
                                      .replace("data.raw", "data.gz"))
    np.testing.assert_array_equal(load_volume(tmp_path / "gz.nhdr").array, values)


@pytest.mark.parametrize("change, message", [
    (("byte skip: -1", "byte skip: -5"), "'byte skip: -5' is invalid"),
    (("endian: little", "endian: middle"), "invalid NRRD endian 'middle'"),
    (("space origin: (0,0,0)", "space origin: (a,b,c)"), "invalid NRRD header"),
    (("space directions: (1,0,0) (0,1,0) (0,0,1)", "space directions: (1,0,0) (0,1) (0,0,1)"), "invalid NRRD header"),
    (("sizes: 30 30 30", "sizes: 30 -30 30"), "'sizes' must be positive"),
    (("type: short", "type: quaternion"), "unsupported NRRD type"),
    (("encoding: gzip", "encoding: hex"), "unsupported NRRD encoding"),
    (("data file: BallBinary30x30x30.nii.gz", "data file: LIST"), "split over several files"),
])
def test_damaged_headers_are_refused(tmp_path, ball, change, message):
    path = _nhdr(tmp_path, "bad.nhdr")
    path.write_text(path.read_text().replace(*change))
    with pytest.raises(VolumeReadError, match=message) as caught:
        load_volume(path)
    assert "bad.nhdr" in str(caught.value) and "\n" not in str(caught.value)


def test_too_much_and_too_little_raw_data(tmp_path):
    values = np.zeros((3, 4, 5), dtype="<i2")
    header = "NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: raw\n\n"
    (tmp_path / "long.nrrd").write_bytes(header.encode() + values.tobytes() + b"\0\0")
    with pytest.raises(CorruptFileError, match="more data than the header declares"):
        load_volume(tmp_path / "long.nrrd")
    (tmp_path / "short.nrrd").write_bytes(header.encode() + values.tobytes()[:-2])
    with pytest.raises(CorruptFileError, match="truncated"):
        load_volume(tmp_path / "short.nrrd")


def test_gzip_crc_error_is_refused(tmp_path):
    values = np.arange(60, dtype="<i2").reshape(3, 4, 5)
    header = "NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: gzip\n\n"
    payload = bytearray(gzip.compress(values.tobytes()))
    payload[-6] ^= 0x55
    (tmp_path / "crc.nrrd").write_bytes(header.encode() + bytes(payload))
    with pytest.raises(CorruptFileError, match="crc.nrrd: the gzip data is damaged"):
        load_volume(tmp_path / "crc.nrrd")


@pytest.mark.timeout(60)  # a hang fails here, with the stacks, instead of stopping the run
def test_special_data_files_and_huge_line_skip_do_not_hang(tmp_path):
    os.mkfifo(tmp_path / "pipe.raw")
    base = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
    (tmp_path / "fifo.nhdr").write_text(base + "data file: pipe.raw\n")
    (tmp_path / "zero.nhdr").write_text(base + "data file: /dev/zero\n")
    (tmp_path / "data.raw").write_bytes(bytes(8))
    (tmp_path / "lines.nhdr").write_text(base + "line skip: 1000000000\ndata file: data.raw\n")
    with pytest.raises(VolumeReadError, match="FIFO"):
        load_volume(tmp_path / "fifo.nhdr")
    with pytest.raises(VolumeReadError, match="device"):
        load_volume(tmp_path / "zero.nhdr")
    with pytest.raises(CorruptFileError, match="skips more lines than the data holds"):
        load_volume(tmp_path / "lines.nhdr")


def test_header_without_end_and_binary_garbage(tmp_path):
    (tmp_path / "open.nrrd").write_bytes(b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n")
    with pytest.raises(CorruptFileError, match="no terminating blank line"):
        load_volume(tmp_path / "open.nrrd")
    (tmp_path / "noise.nrrd").write_bytes(b"NRRD0004" + np.random.default_rng(1).bytes(20000).replace(b"\n", b"x"))
    with pytest.raises(CorruptFileError, match="noise.nrrd"):
        load_volume(tmp_path / "noise.nrrd")


def test_vector_components_keep_the_first(tmp_path):
    values = np.arange(2 * 3 * 4 * 5, dtype="<f4").reshape(5, 4, 3, 2)
    header = ("NRRD0004\ntype: float\ndimension: 4\nsizes: 2 3 4 5\nkinds: vector domain domain domain\n"
              "space: RAS\nspace directions: none (1,0,0) (0,1,0) (0,0,1)\nendian: little\nencoding: raw\n\n")
    (tmp_path / "vec.nrrd").write_bytes(header.encode() + values.tobytes())
    volume = load_volume(tmp_path / "vec.nrrd")
    np.testing.assert_array_equal(volume.array, values[..., 0])
    assert any("2 components per voxel" in w for w in volume.metadata["warnings"])


def test_more_than_three_space_dimensions_refused(tmp_path):
    header = ("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace dimension: 4\n"
              "space directions: (1,0,0,0) (0,1,0,0) (0,0,1,0)\nencoding: raw\n\n")
    (tmp_path / "4d.nrrd").write_bytes(header.encode() + bytes(8))
    with pytest.raises(UnsupportedFormatError, match="space has 4 dimensions"):
        load_volume(tmp_path / "4d.nrrd")
