"""``voxelscope mesh VOLUME.zarr --workers N`` and ``--scheduler ADDRESS`` (issue 19): real processes, a local
cluster and a ``dask scheduler`` with two ``dask worker`` processes started here; both give the in-memory mesh."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from algorithms.common.vtk_bridge import polydata_arrays
from algorithms.compare.triangles import same_triangles
from algorithms.surfaces.marching_cubes import marching_cubes
from app.io.meshes import load_mesh
from app.io.zarr import open_zarr, write_ome_zarr
from app.meshing import to_world

from .test_distributed import gyroid_in_sphere

SPACING = (0.5, 0.75, 1.25)
ORIGIN = (-40.0, 12.5, 3.0)
DASK = Path(sys.executable).parent / "dask"


def voxelscope(*args, check=True):
    process = subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True,
                             timeout=900)
    if check and process.returncode != 0:
        raise AssertionError(f"voxelscope {' '.join(map(str, args))} failed:\n{process.stderr}")
    return process


@pytest.fixture(scope="module")
def store_and_reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("chunked")
    volume = gyroid_in_sphere(96)
    store = write_ome_zarr(volume, folder / "gyroid.zarr", spacing=SPACING, origin=ORIGIN, chunks=40)
    reference = marching_cubes(volume, 0.0, spacing=SPACING, origin=ORIGIN)
    world = to_world(reference.to_polydata(), open_zarr(store))  # the volume frame moved to LPS, as the CLI does
    return store, polydata_arrays(world)


def _same_as_reference(path, reference):
    points, triangles = polydata_arrays(load_mesh(path).polydata)
    assert points.shape == reference[0].shape
    comparison = same_triangles(reference[0], reference[1], points, triangles, rtol=0.0)
    assert comparison.equal and comparison.max_distance == 0.0


@pytest.mark.slow
def test_mesh_with_local_cluster(store_and_reference, tmp_path):
    store, reference = store_and_reference
    output = tmp_path / "local.vtp"
    report = json.loads(voxelscope("mesh", store, "--method", "marching-cubes", "--iso", "0", "--workers", "2",
                                   "-o", output, "--json").stdout)
    assert report["chunked"]["workers"] == 2
    assert report["chunked"]["blocks"] == 27 and report["chunked"]["blocks_skipped"] > 0
    assert report["triangles"] == reference[1].shape[0]
    assert report["validity"]["watertight"] is True  # the ball lies inside the volume: a closed surface
    _same_as_reference(output, reference)


def _scheduler_address(scheduler_file, scheduler, seconds=120.0):
    """The address the scheduler wrote to ``scheduler_file``. dask writes the file in place, so it can exist empty
    or half-written for a moment: read it until it holds a whole JSON document."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        assert scheduler.poll() is None, f"the dask scheduler exited with status {scheduler.returncode}"
        try:
            return json.loads(scheduler_file.read_text())["address"]
        except (FileNotFoundError, json.JSONDecodeError, KeyError):
            time.sleep(0.2)
    raise AssertionError(f"the dask scheduler wrote no address to {scheduler_file} in {seconds:g} s")


@pytest.mark.slow
def test_mesh_with_scheduler_and_two_workers(store_and_reference, tmp_path):
    store, reference = store_and_reference
    scheduler_file = tmp_path / "scheduler.json"
    processes = [subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0",
                                   "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        address = _scheduler_address(scheduler_file, processes[0])
        assert address.startswith("tcp://127.0.0.1:")
        for _ in range(2):
            processes.append(subprocess.Popen([str(DASK), "worker", address, "--nthreads", "1", "--no-dashboard"],
                                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                              start_new_session=True))
        from distributed import Client

        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=120)
        output = tmp_path / "cluster.vtp"
        report = json.loads(voxelscope("mesh", store, "--method", "marching-cubes", "--iso", "0", "--scheduler",
                                       address, "-o", output, "--json").stdout)
        assert report["chunked"]["workers"] == 2
        _same_as_reference(output, reference)
    finally:
        for process in processes:
            os.killpg(process.pid, signal.SIGTERM)
        for process in processes:
            process.wait(timeout=60)


def test_chunked_mesh_errors_are_one_line(store_and_reference, tmp_path):
    store, _ = store_and_reference
    for arguments, expected in (
        (["--method", "flying-edges", "--workers", "1"], "runs in memory only"),
        (["--iso", "1000", "--workers", "1"], "no surface at 1000"),
        (["--workers", "1", "--scheduler", "tcp://127.0.0.1:1"], "not allowed with"),
        (["--scheduler", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler"),
    ):
        method = [] if "--method" in arguments else ["--method", "marching-cubes"]
        process = voxelscope("mesh", store, *method, *arguments, "-o", tmp_path / "x.vtp", check=False)
        assert process.returncode != 0
        assert "Traceback" not in process.stderr
        assert expected in process.stderr, process.stderr
    nifti = tmp_path / "v.nii"
    from app.io import save_volume
    from app.volume import Volume

    save_volume(Volume(np.zeros((4, 4, 4), np.int16)), nifti)
    process = voxelscope("mesh", nifti, "--method", "marching-cubes", "--workers", "1", "-o", tmp_path / "y.vtp",
                         check=False)
    assert "convert the volume first" in process.stderr
