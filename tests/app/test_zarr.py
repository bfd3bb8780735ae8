"""OME-Zarr reading and writing (issue 19): round trip through ``voxelscope convert``, the metadata as the
``ome-zarr`` package reads it, the pyramid, and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from app.io import VolumeReadError, load_volume, open_zarr, save_volume, volume_format
from app.io.zarr import write_ome_zarr
from app.volume import Volume

ROTATED = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def voxelscope(*args, check=True):
    process = subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True,
                             timeout=600)
    if check and process.returncode != 0:
        raise AssertionError(f"voxelscope {' '.join(map(str, args))} failed:\n{process.stderr}")
    return process


def _volume(shape=(70, 90, 150)) -> Volume:
    rng = np.random.default_rng(19)
    array = (rng.normal(100.0, 300.0, shape)).astype(np.int16)
    return Volume(array, (0.6, 0.8, 1.25), (-12.5, 30.25, -80.0), ROTATED, "CT", "HU")


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_convert_round_trip_and_ome_zarr_reader(tmp_path, zarr_format):
    ome_io = pytest.importorskip("ome_zarr.io")
    ome_reader = pytest.importorskip("ome_zarr.reader")
    original = _volume()
    source = save_volume(original, tmp_path / "in.nrrd")
    target = tmp_path / "out.ome.zarr"
    output = voxelscope("convert", source, "-o", target, "--chunks", "32", "--zarr-format", zarr_format,
                        "--compressor", "blosc-zstd", "--json").stdout
    assert json.loads(output)["output"] == str(target)
    assert volume_format(target) == "Zarr"

    back = load_volume(target)
    assert back.dimensions == original.dimensions
    np.testing.assert_array_equal(back.array, original.array)
    np.testing.assert_allclose(back.spacing, original.spacing, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.origin, original.origin, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.direction, original.direction, atol=1e-12)
    assert (back.modality, back.units) == ("CT", "HU")

    chunked = open_zarr(target)
    assert len(chunked.levels) == 2  # 150 samples > 128: one halved level
    assert chunked.levels[0].chunks == (32, 32, 32)
    assert chunked.levels[1].shape == (35, 45, 75)
    # The coarse level is the mean of 2x2x2 blocks, placed at their centres.
    expected = np.round(original.array[:70, :90, :150].astype(np.float64)
                        .reshape(35, 2, 45, 2, 75, 2).mean(axis=(1, 3, 5))).astype(np.int16)
    np.testing.assert_array_equal(chunked.region(1, (slice(None),) * 3), expected)
    np.testing.assert_allclose(chunked.levels[1].origin, np.asarray(original.origin) + 0.5 * np.asarray(original.spacing))

    # The ome-zarr package's reader sees the same scales, translations and axes.
    nodes = list(ome_reader.Reader(ome_io.parse_url(str(target)))())
    image = nodes[0]
    assert [axis["name"] for axis in image.metadata["axes"]] == ["z", "y", "x"]
    assert {axis["type"] for axis in image.metadata["axes"]} == {"space"}
    assert {axis["unit"] for axis in image.metadata["axes"]} == {"millimeter"}
    transforms = image.metadata["coordinateTransformations"]
    assert len(transforms) == len(chunked.levels) == len(image.data)
    for level, transform, data in zip(chunked.levels, transforms, image.data):
        scale = next(t["scale"] for t in transform if t["type"] == "scale")
        translation = next(t["translation"] for t in transform if t["type"] == "translation")
        np.testing.assert_allclose(scale[::-1], level.spacing)
        np.testing.assert_allclose(translation[::-1], level.origin)
        assert tuple(data.shape) == level.shape
    np.testing.assert_array_equal(np.asarray(image.data[0]), original.array)


def test_info_reads_metadata_of_a_chunked_volume(tmp_path):
    original = _volume((20, 30, 40))
    target = write_ome_zarr(original.array, tmp_path / "v.zarr", spacing=original.spacing, origin=original.origin,
                            chunks=16)
    chunked = open_zarr(target)
    facts = chunked.describe()
    assert facts["dimensions"] == [40, 30, 20]
    assert facts["range"] == [float(original.array.min()), float(original.array.max())]
    ranges = chunked.chunk_range()
    assert ranges.shape == (2, 2, 3, 2)
    np.testing.assert_array_equal(ranges[1, 0, 2], [original.array[16:, :16, 32:].min(),
                                                    original.array[16:, :16, 32:].max()])
    # info reads the metadata only: it works with every chunk of samples gone.
    chunk_files = [f for f in (target / "0").iterdir() if not f.name.startswith(".")]
    assert len(chunk_files) == 12
    for chunk_file in chunk_files:
        chunk_file.unlink()
    data = json.loads(voxelscope("info", target, "--json").stdout)
    assert data["dimensions"] == [40, 30, 20] and data["spacing"] == list(original.spacing)


def test_errors_are_one_line(tmp_path):
    original = _volume((20, 30, 40))
    target = write_ome_zarr(original.array, tmp_path / "v.zarr", chunks=16)
    with pytest.raises(Exception, match="exists"):
        write_ome_zarr(original.array, target, chunks=16)
    chunked = open_zarr(target)
    with pytest.raises(VolumeReadError, match="GiB in memory"):
        chunked.volume(0, budget=1000)
    (tmp_path / "empty.zarr").mkdir()
    process = voxelscope("info", tmp_path / "empty.zarr", check=False)
    assert process.returncode != 0
    assert "Traceback" not in process.stderr
    assert len(process.stderr.strip().splitlines()) == 1
    assert "Zarr metadata" in process.stderr


def test_a_pyramid_too_large_for_the_budget_opens_at_a_coarser_level(tmp_path):
    from app.io.zarr import read_zarr

    original = _volume((40, 64, 150))
    target = write_ome_zarr(original.array, tmp_path / "p.zarr", spacing=original.spacing, origin=original.origin,
                            chunks=32)
    chunked = open_zarr(target)
    coarse = read_zarr(target, budget=chunked.nbytes(1))
    assert coarse.dimensions == (75, 32, 20)
    np.testing.assert_allclose(coarse.spacing, 2 * np.asarray(original.spacing))
    assert any("opened pyramid level 1" in warning for warning in coarse.metadata["warnings"])
    assert read_zarr(target).dimensions == original.dimensions  # fits the default budget: full resolution
    with pytest.raises(VolumeReadError, match="GiB in memory"):
        read_zarr(target, level=0, budget=1000)
