"""Chunked marching cubes (issue 19): the stitched mesh of a chunked volume IS the in-memory mesh - same triangles
(compared as sets with zero tolerance), same shared vertices - whatever the chunk size, so seams fall everywhere."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from algorithms.compare.triangles import same_triangles
from algorithms.surfaces.marching_cubes import marching_cubes
from algorithms.surfaces.marching_cubes.blocks import marching_cubes_block
from app.distributed import mesh_chunked
from app.distributed.chunked import plan_blocks
from app.io.zarr import open_zarr, write_ome_zarr

SPACING = (0.5, 0.75, 1.25)
ORIGIN = (-40.0, 12.5, 3.0)


def gyroid_in_sphere(n: int) -> np.ndarray:
    """Integer samples (many exactly at the isovalue 0, so vertices on samples are merged across seams) of a
    gyroid inside a ball; outside the ball every sample is -500, so whole chunks have no surface."""
    z, y, x = np.ogrid[:n, :n, :n]
    scale = 0.11
    field = (np.sin(x * scale) * np.cos(y * scale) + np.sin(y * scale) * np.cos(z * scale)
             + np.sin(z * scale) * np.cos(x * scale))
    values = np.round(100 * field).astype(np.int16)
    centre = (n - 1) / 2
    outside = (x - centre) ** 2 + (y - centre) ** 2 + (z - centre) ** 2 > (0.28 * n) ** 2
    values[outside] = -500
    return values


def assert_same_mesh(reference, points, triangles):
    assert points.shape == reference.points.shape  # the same shared vertices: one per position
    np.testing.assert_array_equal(np.unique(points, axis=0), np.unique(reference.points, axis=0))
    comparison = same_triangles(reference.points, reference.triangles, points, triangles, rtol=0.0)
    assert comparison.equal, (len(comparison.unmatched_a), len(comparison.unmatched_b))
    assert comparison.max_distance == 0.0


@pytest.mark.slow
def test_chunked_mesh_equals_in_memory_mesh_384(tmp_path):
    volume = gyroid_in_sphere(384)
    reference = marching_cubes(volume, 0.0, spacing=SPACING, origin=ORIGIN)
    assert reference.triangles.shape[0] > 500_000
    for chunks in (64, 100, 128):
        store = write_ome_zarr(volume, tmp_path / f"v{chunks}.zarr", spacing=SPACING, origin=ORIGIN, chunks=chunks,
                               levels=1)
        result = mesh_chunked(open_zarr(store), 0.0)
        assert result.stats["blocks_skipped"] > 0, result.stats  # the corners outside the ball are never read
        assert result.stats["blocks_meshed"] + result.stats["blocks_skipped"] == int(np.ceil(383 / chunks)) ** 3
        assert_same_mesh(reference, result.points, result.triangles)
        shutil.rmtree(store)


def test_chunked_mesh_equals_in_memory_mesh_float_and_first_pass(tmp_path):
    rng = np.random.default_rng(7)
    volume = rng.normal(0.0, 1.0, (61, 70, 83)).astype(np.float32)
    reference = marching_cubes(volume, 0.3, spacing=SPACING, origin=ORIGIN)
    store = write_ome_zarr(volume, tmp_path / "noise.zarr", spacing=SPACING, origin=ORIGIN, chunks=23, levels=1)
    shutil.rmtree(store / "chunk_range")  # a store from another writer: min/max come from a first pass
    result = mesh_chunked(open_zarr(store), 0.3)
    assert result.stats["first_pass"]
    assert_same_mesh(reference, result.points, result.triangles)


def test_plan_skips_only_chunks_the_surface_cannot_reach():
    ranges = np.zeros((2, 2, 2, 2))
    ranges[..., 1] = 1.0  # every chunk spans 0..1 except ...
    ranges[1, 1, 1] = (5.0, 6.0)  # ... the last, entirely above 2
    blocks, skipped = plan_blocks((20, 20, 20), (10, 10, 10), 2.0, ranges)
    # The last block (all its samples above 2, no overlap beyond the end) is skipped; every other block's overlap
    # reaches into the last chunk, so the surface may cross it.
    assert skipped == 1 and len(blocks) == 7 and ((10, 10, 10), (20, 20, 20)) not in blocks
    blocks, skipped = plan_blocks((20, 20, 20), (10, 10, 10), 7.0, ranges)
    assert (blocks, skipped) == ([], 8)
    ranges[...] = (0.0, 3.0)  # every chunk crossed
    blocks, skipped = plan_blocks((20, 20, 20), (10, 10, 10), 2.0, ranges)
    assert skipped == 0 and blocks[0] == ((0, 0, 0), (11, 11, 11)) and blocks[-1] == ((10, 10, 10), (20, 20, 20))


def test_block_errors():
    block = np.zeros((5, 5, 5), np.float32)
    with pytest.raises(ValueError, match="does not lie inside"):
        marching_cubes_block(block, 0.5, start=(10, 0, 0), volume_shape=(12, 12, 12))
    with pytest.raises(ValueError, match="one isovalue"):
        marching_cubes_block(block, [0.5, 0.7], start=(0, 0, 0), volume_shape=(12, 12, 12))
    block[2, 2, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        marching_cubes_block(block, 0.5, start=(0, 0, 0), volume_shape=(12, 12, 12))
    empty = marching_cubes_block(np.zeros((4, 4, 4)), 0.5, start=(0, 0, 0), volume_shape=(4, 4, 4))
    assert empty.triangles.shape == (0, 3)


def test_progress_rises_and_cancel_stops_the_run(tmp_path):
    from algorithms.common.progress import OperationCancelled

    volume = np.random.default_rng(3).normal(0.0, 1.0, (40, 40, 40)).astype(np.float32)
    store = write_ome_zarr(volume, tmp_path / "n.zarr", chunks=16, levels=1)
    fractions = []
    mesh_chunked(open_zarr(store), 0.0, progress=fractions.append)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0 and len(fractions) >= 27

    def cancel_after_three(fraction):
        if len(fractions) > 3:
            raise OperationCancelled()
        fractions.append(fraction)

    fractions = []
    with pytest.raises(OperationCancelled):
        mesh_chunked(open_zarr(store), 0.0, progress=cancel_after_three)
