"""Volume writers on a full disk, over existing files and companions, and the clean-up of stale temporaries."""

from __future__ import annotations

import errno
import os
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from app.io import FileExistsRefusal, VolumeWriteError, load_volume, save_volume
from app.io import atomic
from app.io.atomic import TEMP_PREFIX, atomic_output, remove_stale_temporaries
from app.volume import Volume

SUFFIXES = [".nii", ".nii.gz", ".nrrd", ".mha", ".mhd", ".vti"]


def _volume(shape=(20, 40, 40)) -> Volume:
    values = np.random.default_rng(0).integers(-1000, 1000, shape).astype(np.int16)  # does not compress away
    return Volume(values, spacing=(0.5, 0.5, 1.0), modality="CT", units="HU")


def _left(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_injected_full_disk_leaves_nothing(tmp_path, monkeypatch, suffix):
    def full(handle):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    target = tmp_path / f"out{suffix}"
    with pytest.raises(VolumeWriteError) as caught:
        save_volume(_volume(), target)
    message = str(caught.value)
    assert message == f"{target}: could not be written: the disk is full (no space left on device)"
    assert TEMP_PREFIX not in message
    assert _left(tmp_path) == []


@pytest.fixture
def tiny_disk(tmp_path):
    """A 64 KiB tmpfs (needs root and mount rights; skipped otherwise)."""
    mount = tmp_path / "tiny"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here ({done.stderr.decode().strip() or 'not root'})")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=False)


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_real_full_disk(tiny_disk, suffix):
    small = _volume((2, 8, 8))
    existing = save_volume(small, tiny_disk / f"out{suffix}")
    before = {p.name: p.read_bytes() for p in tiny_disk.iterdir()}
    with pytest.raises(VolumeWriteError, match=rf"^{tiny_disk}/out{suffix.replace('.', '[.]')}: could not be written: "
                                               r"the disk is full"):
        save_volume(_volume((40, 40, 40)), existing, overwrite=True)
    # The old file (and its companion) are untouched, and no temporary file is left.
    assert {p.name: p.read_bytes() for p in tiny_disk.iterdir()} == before
    np.testing.assert_array_equal(load_volume(existing).array, small.array)


def test_companion_is_checked_before_anything_is_written(tmp_path):
    (tmp_path / "x.zraw").write_bytes(b"someone else's data")
    with pytest.raises(FileExistsRefusal, match="x.zraw already exists"):
        save_volume(_volume(), tmp_path / "x.mhd")
    assert _left(tmp_path) == ["x.zraw"]  # no x.mhd, no orphan, no temporary file
    save_volume(_volume(), tmp_path / "x.mhd", overwrite=True)
    assert _left(tmp_path) == ["x.mhd", "x.zraw"]
    assert load_volume(tmp_path / "x.mhd").dimensions == (40, 40, 20)


def test_header_and_data_land_together(tmp_path, monkeypatch):
    calls = []
    real_replace = os.replace

    def second_fails(source, target):
        calls.append(target)
        if len(calls) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real_replace(source, target)

    monkeypatch.setattr(atomic.os, "replace", second_fails)
    with pytest.raises(VolumeWriteError, match=r"x\.mhd: could not be written: Input/output error"):
        save_volume(_volume(), tmp_path / "x.mhd")
    assert _left(tmp_path) == []  # the data file renamed first was taken back


def test_target_that_is_a_folder(tmp_path):
    (tmp_path / "out.nii").mkdir()
    with pytest.raises(VolumeWriteError) as caught:
        save_volume(_volume(), tmp_path / "out.nii", overwrite=True)
    assert str(caught.value) == f"{tmp_path / 'out.nii'} is a folder; give a file name for the output"


def test_stale_temporaries_are_removed(tmp_path):
    stale = tmp_path / f"{TEMP_PREFIX}old-0a1b2c3d.nii"
    fresh = tmp_path / f"{TEMP_PREFIX}running-4e5f6a7b.nii"
    other = tmp_path / ".hidden-user-file"
    for path in (stale, fresh, other):
        path.write_bytes(b"x")
    two_hours_ago = time.time() - 7200
    os.utime(stale, (two_hours_ago, two_hours_ago))
    os.utime(other, (two_hours_ago, two_hours_ago))
    save_volume(_volume((2, 4, 4)), tmp_path / "new.nrrd")
    assert _left(tmp_path) == sorted([fresh.name, other.name, "new.nrrd"])
    assert remove_stale_temporaries(tmp_path, max_age=0) == [fresh]


def test_writer_errors_name_the_target_not_the_temporary(tmp_path):
    with pytest.raises(VolumeWriteError) as caught:
        with atomic_output(tmp_path / "result.vti") as temporary:
            raise RuntimeError(f"vtkXMLImageDataWriter: cannot open {temporary}")
    assert str(caught.value) == f"vtkXMLImageDataWriter: cannot open {tmp_path / 'result.vti'}"
    assert _left(tmp_path) == []


def test_cancelling_inside_an_atomic_write_is_not_a_write_error(tmp_path):
    class Cancelled(Exception):
        pass

    with pytest.raises(Cancelled):
        with atomic_output(tmp_path / "a.nrrd") as temporary:
            temporary.write_bytes(b"partial")
            raise Cancelled()
    assert _left(tmp_path) == []


def test_temporary_names_are_recognisable_and_keep_the_extension(tmp_path):
    with atomic_output(tmp_path / "scan.nii.gz") as temporary:
        assert temporary.name.startswith(f"{TEMP_PREFIX}scan-") and temporary.name.endswith(".nii.gz")
        temporary.write_bytes(b"data")
    assert _left(tmp_path) == ["scan.nii.gz"]
    mask = os.umask(0)
    os.umask(mask)
    assert (tmp_path / "scan.nii.gz").stat().st_mode & 0o777 == 0o666 & ~mask  # not the 0600 of a temporary


def test_a_vtk_writer_that_cannot_open_its_file_is_an_error(tmp_path):
    """VTK writers report a failure through an error event, not an exception: ``write_with_vtk`` raises it."""
    from vtkmodules.vtkIOImage import vtkPNGWriter

    from app.io.vtk_writing import write_with_vtk

    image = Volume(np.zeros((1, 8, 8), dtype=np.uint8), spacing=(1.0, 1.0, 1.0)).to_vtk()
    with pytest.raises(OSError, match="CannotOpenFileError") as caught:
        write_with_vtk(vtkPNGWriter, image, tmp_path / "no such folder" / "x.png")
    assert caught.value.errno == errno.EIO
    write_with_vtk(vtkPNGWriter, image, tmp_path / "x.png")  # the same call on a good path writes
    assert (tmp_path / "x.png").stat().st_size > 0


def test_a_screenshot_on_a_full_disk_is_refused_and_leaves_nothing(tiny_disk):
    from app.pipeline.offscreen import write_png

    noise = np.random.default_rng(1).integers(0, 256, (400, 400, 3), dtype=np.uint8)  # about 480 kB as PNG
    with pytest.raises(VolumeWriteError, match=rf"^{tiny_disk}/shot\.png: could not be written: the disk is full"):
        write_png(noise, tiny_disk / "shot.png")
    assert _left(tiny_disk) == []
