"""Mesh files (issue 20): every format written by us or checked, on a full disk, with its sidecar.

For STL, PLY, OBJ and VTP: the file reads back as the surface written; a full disk - a real 64 KiB tmpfs when this
machine lets us mount one, and an injected ``ENOSPC`` everywhere - is a one-line error naming the user's file, the
target (and an existing file there) is untouched, and no temporary file is left; the mesh and its sidecar land
together or not at all; stale temporary files of killed runs are removed; a folder as the target is named as such.
"""

from __future__ import annotations

import builtins
import errno
import json
import os
import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOGeometry import vtkOBJReader
from vtkmodules.vtkIOPLY import vtkPLYReader
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

from algorithms.datasets.volumes import sphere_field
from app import mesh_files, meshing
from app.io.atomic import TEMP_PREFIX
from app.io.errors import FileExistsRefusal, VolumeWriteError
from app.io.meshes import describe_mesh, load_mesh
from app.mesh_files import MESH_SUFFIXES, sidecar_path, write_mesh_files
from app.volume import Volume

FULL = "could not be written: the disk is full (no space left on device)"


def _left(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture(scope="module")
def sphere():
    """A closed marching-cubes sphere in world coordinates with point normals (about 12,000 triangles)."""
    volume = Volume(sphere_field((40, 40, 40), 15.0).astype(np.float32), spacing=(0.8, 0.8, 1.2))
    return meshing.surface_for_export(volume, method="marching-cubes", iso=0.0).polydata


def _arrays(polydata):
    points, triangles, normals = mesh_files.mesh_arrays(polydata)
    return points, triangles, normals


@pytest.mark.parametrize("suffix", MESH_SUFFIXES)
def test_round_trip(sphere, tmp_path, suffix):
    path = tmp_path / f"ball{suffix}"
    assert write_mesh_files(sphere, path, sidecar={"note": "x"}) == [path, sidecar_path(path)]
    assert json.loads(sidecar_path(path).read_text()) == {"note": "x"}
    mesh = load_mesh(path)
    points, triangles, normals = _arrays(sphere)
    read_points, read_triangles, _ = _arrays(mesh.polydata)
    assert len(read_triangles) == len(triangles)
    # Same triangles in the same order (STL stores corners, which the reader merges back into points).
    np.testing.assert_allclose(read_points[read_triangles], points[triangles], rtol=0, atol=1e-5)
    description = describe_mesh(mesh)
    assert description["closed"] and description["orientation"] == "outward"
    if suffix in (".ply", ".obj", ".vtp"):  # point normals kept (STL stores facet normals)
        reader = {".ply": vtkPLYReader, ".obj": vtkOBJReader, ".vtp": vtkXMLPolyDataReader}[suffix]()
        reader.SetFileName(str(path))
        reader.Update()
        read_normals = vtk_to_numpy(reader.GetOutput().GetPointData().GetNormals())
        assert read_normals.shape == normals.shape
        np.testing.assert_allclose(np.abs(read_normals).sum(), np.abs(normals).sum(), rtol=1e-6)
    if suffix == ".stl":
        assert path.stat().st_size == 84 + 50 * len(triangles)


@pytest.mark.parametrize("suffix", MESH_SUFFIXES)
def test_injected_full_disk_at_flush(sphere, tmp_path, monkeypatch, suffix):
    def full(handle):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    target = tmp_path / f"out{suffix}"
    with pytest.raises(VolumeWriteError) as caught:
        write_mesh_files(sphere, target, sidecar={"a": 1})
    assert str(caught.value) == f"{target}: {FULL}"
    assert _left(tmp_path) == []


@pytest.mark.parametrize("suffix", [".stl", ".ply", ".obj"])
def test_injected_full_disk_while_writing(sphere, tmp_path, monkeypatch, suffix):
    """The disk fills up half-way through the data: Python's file raises, nothing lands."""
    real_open = builtins.open

    class Filling:
        def __init__(self, handle):
            self.handle, self.written = handle, 0

        def write(self, data):
            self.written += len(data)
            if self.written > 20_000:
                raise OSError(errno.ENOSPC, "No space left on device")
            return self.handle.write(data)

        def __getattr__(self, name):
            return getattr(self.handle, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

    def filling_open(path, mode="r", *args, **kwargs):
        handle = real_open(path, mode, *args, **kwargs)
        return Filling(handle) if "w" in mode and TEMP_PREFIX in str(path) else handle

    monkeypatch.setattr(mesh_files, "open", filling_open, raising=False)
    target = tmp_path / f"out{suffix}"
    target.write_bytes(b"the user's old file")
    with pytest.raises(VolumeWriteError, match="^" + re.escape(f"{target}: {FULL}")):
        write_mesh_files(sphere, target, sidecar={"a": 1}, overwrite=True)
    assert _left(tmp_path) == [target.name] and target.read_bytes() == b"the user's old file"


def test_short_write_is_caught_by_the_size_check(sphere, tmp_path, monkeypatch):
    """A writer that loses bytes without an error (as VTK's did) cannot hand over a truncated STL or PLY."""
    real = mesh_files._WRITERS[".stl"]

    def lossy(handle, *args):
        expected = real(handle, *args)
        handle.truncate(expected - 50)
        return expected

    monkeypatch.setitem(mesh_files._WRITERS, ".stl", lossy)
    with pytest.raises(VolumeWriteError, match=r"out\.stl: could not be written: \d+ of \d+ bytes reached the disk"):
        write_mesh_files(sphere, tmp_path / "out.stl")
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


@pytest.mark.parametrize("suffix", MESH_SUFFIXES)
def test_real_full_disk(sphere, tiny_disk, suffix):
    small = meshing.surface_for_export(Volume(sphere_field((8, 8, 8), 2.5).astype(np.float32)),
                                       method="marching-cubes", iso=0.0).polydata
    existing = tiny_disk / f"out{suffix}"
    write_mesh_files(small, existing, sidecar={"old": True})
    before = {p.name: p.read_bytes() for p in tiny_disk.iterdir()}
    with pytest.raises(VolumeWriteError, match="^" + re.escape(f"{existing}: {FULL}")):
        write_mesh_files(sphere, existing, sidecar={"new": True}, overwrite=True)
    # The old mesh and its sidecar are untouched, and no temporary file is left.
    assert {p.name: p.read_bytes() for p in tiny_disk.iterdir()} == before


def test_command_line_on_a_full_disk(tiny_disk):
    target = tiny_disk / "skull.obj"
    process = subprocess.run([os.sys.executable, "-m", "app.cli", "mesh", "sample", "-o", str(target)],
                             capture_output=True, text=True, timeout=600)
    assert process.returncode == 1
    assert process.stderr.strip() == f"voxelscope: error: {target}: {FULL}"
    assert _left(tiny_disk) == []


def test_mesh_and_sidecar_land_together(sphere, tmp_path, monkeypatch):
    def no_room(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_text", no_room)
    target = tmp_path / "ball.ply"
    with pytest.raises(VolumeWriteError) as caught:
        write_mesh_files(sphere, target, sidecar={"a": 1})
    message = str(caught.value)
    assert message == (f"{sidecar_path(target)}: {FULL} (the sidecar of ball.ply; neither file was written)")
    assert _left(tmp_path) == []


def test_rename_failure_takes_the_sidecar_back(sphere, tmp_path, monkeypatch):
    from app.io import atomic

    calls = []
    real_replace = os.replace

    def second_fails(source, target):
        calls.append(target)
        if len(calls) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real_replace(source, target)

    monkeypatch.setattr(atomic.os, "replace", second_fails)
    with pytest.raises(VolumeWriteError, match=r"ball\.stl: could not be written: Input/output error"):
        write_mesh_files(sphere, tmp_path / "ball.stl", sidecar={"a": 1})
    assert calls[0] == sidecar_path(tmp_path / "ball.stl")  # the sidecar first, the mesh last
    assert _left(tmp_path) == []


def test_existing_files_and_folders(sphere, tmp_path):
    (tmp_path / "ball.stl.json").write_text("{}")
    with pytest.raises(FileExistsRefusal, match="ball.stl.json already exists"):
        write_mesh_files(sphere, tmp_path / "ball.stl", sidecar={"a": 1})
    assert _left(tmp_path) == ["ball.stl.json"]
    (tmp_path / "folder.stl").mkdir()
    with pytest.raises(VolumeWriteError) as caught:
        write_mesh_files(sphere, tmp_path / "folder.stl", overwrite=True)
    assert str(caught.value) == f"{tmp_path / 'folder.stl'} is a folder; give a file name for the output"
    with pytest.raises(VolumeWriteError, match=r"missing/ball\.stl: the folder .*missing does not exist"):
        write_mesh_files(sphere, tmp_path / "missing" / "ball.stl")
    with pytest.raises(VolumeWriteError, match=r"ball\.3mf: unknown mesh format '\.3mf'"):
        write_mesh_files(sphere, tmp_path / "ball.3mf")


def test_stale_temporaries_of_killed_runs_are_removed(sphere, tmp_path):
    stale = tmp_path / f"{TEMP_PREFIX}skull-0a1b2c3d.stl"
    fresh = tmp_path / f"{TEMP_PREFIX}running-4e5f6a7b.ply"
    for path in (stale, fresh):
        path.write_bytes(b"partial")
    two_hours_ago = time.time() - 7200
    os.utime(stale, (two_hours_ago, two_hours_ago))
    write_mesh_files(sphere, tmp_path / "ball.obj", sidecar={"a": 1})
    assert _left(tmp_path) == sorted([fresh.name, "ball.obj", "ball.obj.json"])
