"""Showing a large OME-Zarr pyramid (issue 19): the part of the volume in view, the level and region to read when
zoomed, the region's samples and geometry, opening at a coarse level; and the parallel block writer."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from algorithms.common.camera import Camera
from app.io.zarr import open_zarr, write_ome_zarr
from app.io.zarr_blocks import write_ome_zarr_blocks
from app.pyramid_view import load_pyramid_for_view, plan_region, read_region, visible_box
from app.volume import Volume

ROTATED = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _brute_force_visible(camera, aspect, lo, hi, n=60):
    """AABB of grid points of the box whose projection falls inside the viewport (and in front of the eye)."""
    axes = [np.linspace(a, b, n) for a, b in zip(lo, hi)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    width, height = 1000 * aspect, 1000
    right, up, forward = camera.basis()
    front = (points - np.asarray(camera.position)) @ forward > 0
    pixels = camera.project(points, width, height)
    inside = front & (pixels[:, 0] >= 0) & (pixels[:, 0] <= width) & (pixels[:, 1] >= 0) & (pixels[:, 1] <= height)
    if camera.parallel_projection:
        inside = (pixels[:, 0] >= 0) & (pixels[:, 0] <= width) & (pixels[:, 1] >= 0) & (pixels[:, 1] <= height)
    chosen = points[inside]
    eye = np.asarray(camera.position)
    if not camera.parallel_projection and np.all((eye >= lo) & (eye <= hi)):
        chosen = np.vstack([chosen, eye])  # the frustum's apex: in the closure of the visible part
    return chosen.min(axis=0), chosen.max(axis=0), (hi - lo) / (n - 1)


@pytest.mark.parametrize("camera", [
    Camera((500.0, -200.0, 300.0), (50.0, 40.0, 30.0), (0.0, 0.0, 1.0), 30.0),  # whole box in view
    Camera((60.0, -30.0, 40.0), (55.0, 45.0, 30.0), (0.0, 0.0, 1.0), 20.0),  # zoomed in, eye outside the box
    Camera((40.0, 40.0, 30.0), (70.0, 60.0, 35.0), (0.3, 0.0, 1.0), 25.0),  # eye inside the box
    Camera((50.0, -500.0, 30.0), (50.0, 40.0, 30.0), (0.0, 0.0, 1.0), 30.0, True, 12.0),  # parallel, zoomed in
    Camera((50.0, 40.0, 400.0), (30.0, 20.0, 30.0), (0.0, 1.0, 0.0), 30.0, True, 400.0),  # parallel, zoomed out
])
@pytest.mark.parametrize("aspect", [1.0, 1.7])
def test_visible_box_matches_brute_force(camera, aspect):
    lo, hi = np.zeros(3), np.array([100.0, 80.0, 60.0])
    box = visible_box(camera, aspect, lo, hi)
    want_lo, want_hi, step = _brute_force_visible(camera, aspect, lo, hi)
    assert box is not None
    # The exact box contains every visible grid point and is at most one grid step larger on each side.
    assert np.all(box[0] <= want_lo + 1e-9) and np.all(box[1] >= want_hi - 1e-9)
    assert np.all(box[0] >= want_lo - step - 1e-9) and np.all(box[1] <= want_hi + step + 1e-9)


def test_visible_box_is_none_when_looking_away():
    camera = Camera((50.0, -100.0, 30.0), (50.0, -300.0, 30.0), (0.0, 0.0, 1.0), 30.0)
    assert visible_box(camera, 1.0, np.zeros(3), np.array([100.0, 80.0, 60.0])) is None


@pytest.fixture(scope="module")
def pyramid(tmp_path_factory):
    """A 256^3 uint16 pyramid (levels 256, 128, 64) with an oblique direction and an offset origin."""
    z, y, x = np.ogrid[:256, :256, :256]
    array = (1000 + 30 * x + 7 * y + 3 * z + (x * y) % 11).astype(np.uint16)
    store = write_ome_zarr(array, tmp_path_factory.mktemp("pyr") / "p.zarr", spacing=(0.5, 0.4, 0.3),
                           origin=(-20.0, 10.0, 5.0), direction=ROTATED, chunks=64, levels=3)
    return store, array


def _camera_at(volume: Volume, ijk, distance_mm: float, scale: float | None = None) -> Camera:
    focal = volume.index_to_world(np.asarray(ijk, float))
    forward = volume.direction @ np.array([0.0, 1.0, 0.0])  # looking along +j
    position = focal - distance_mm * forward
    up = volume.direction @ np.array([0.0, 0.0, 1.0])
    if scale is None:
        return Camera(tuple(position), tuple(focal), tuple(up), 30.0)
    return Camera(tuple(position), tuple(focal), tuple(up), 30.0, True, scale)


def test_plan_read_and_geometry_of_the_region_in_view(pyramid):
    store, array = pyramid
    chunked = open_zarr(store)
    coarse = load_pyramid_for_view(store, budget=64**3 * 2)
    assert coarse.metadata["level"] == 2 and coarse.dimensions == (64, 64, 64)
    assert coarse.metadata["pyramid"]["levels"] == 3
    level0 = Volume(array, chunked.spacing, chunked.origin, chunked.direction)
    # Zoomed out: the coarse level is all there is to show.
    far = _camera_at(level0, (128, -2000, 128), 100.0, scale=200.0)
    assert plan_region(chunked, far, 1.0, coarse_level=2, budget=64**3 * 2) is None
    # Zoomed in on a small part (parallel, 8 mm half height at 0.3-0.5 mm voxels): level 0 fits the budget.
    near = _camera_at(level0, (100, 128, 150), 100.0, scale=8.0)
    plan = plan_region(chunked, near, 1.0, coarse_level=2, budget=2 << 20)
    assert plan is not None and plan.level == 0
    (k0, j0, i0), (k1, j1, i1) = plan.start, plan.stop
    # The visible part: +-8 mm around the focal point along i (0.5 mm) and k (0.3 mm), all of j (depth).
    assert abs(i0 - (100 - 16)) <= 2 and abs(i1 - (100 + 16)) <= 3
    assert abs(k0 - (150 - 27)) <= 2 and abs(k1 - (150 + 27)) <= 3
    assert (j0, j1) == (0, 256)
    region = read_region(chunked, plan, value_range=coarse.value_range)
    np.testing.assert_array_equal(region.array, array[k0:k1, j0:j1, i0:i1])
    assert region.spacing == chunked.spacing
    np.testing.assert_allclose(region.direction, ROTATED)
    # Lines up with the full-resolution volume: the same sample lies at the same place.
    np.testing.assert_allclose(region.index_to_world([5, 7, 9]), level0.index_to_world([i0 + 5, j0 + 7, k0 + 9]),
                               atol=1e-9)
    assert region.value_range == coarse.value_range
    assert region.metadata["pyramid"]["region"] == [list(plan.start), list(plan.stop)]
    # A tighter budget picks the next level, whose region covers the same part of the volume.
    plan1 = plan_region(chunked, near, 1.0, coarse_level=2, budget=plan.nbytes(2) // 4)
    assert plan1 is not None and plan1.level == 1
    assert abs(plan1.start[2] * 2 - i0) <= 4 and abs(plan1.stop[2] * 2 - i1) <= 4
    with pytest.raises(ValueError, match="more than"):
        read_region(chunked, plan, budget=plan.nbytes(2) - 1)


def test_read_region_can_be_cancelled(pyramid):
    from algorithms.common.progress import OperationCancelled

    store, _ = pyramid
    chunked = open_zarr(store)
    from app.pyramid_view import RegionPlan

    def cancel(fraction):
        if fraction > 0.2:
            raise OperationCancelled("cancelled")

    with pytest.raises(OperationCancelled):
        read_region(chunked, RegionPlan(0, (0, 0, 0), (256, 64, 64)), progress=cancel)


def _ramp_block(n, z0, z1, y0, y1, x0, x1):
    z, y, x = np.ogrid[z0:z1, y0:y1, x0:x1]
    return ((x * 7 + y * 13 + z * 29 + (x * y * z) % 17) % 4000).astype(np.uint16)


def _fixed_block(*bounds):
    return np.zeros((8, 8, 8), np.uint16)  # wrong at the ends of a 9^3 volume


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_block_writer_equals_the_dask_writer(tmp_path, zarr_format):
    n = 90  # chunks of 32: partial chunks at the ends of every axis, 3 levels (90, 45, 22)
    whole = _ramp_block(n, 0, n, 0, n, 0, n)
    seen = []
    blocks = write_ome_zarr_blocks(partial(_ramp_block, n), (n, n, n), np.uint16, tmp_path / "b.zarr",
                                   spacing=(0.5, 0.6, 0.7), origin=(1.0, 2.0, 3.0), chunks=32, levels=3,
                                   zarr_format=zarr_format, workers=2, progress=seen.append)
    dask = write_ome_zarr(whole, tmp_path / "d.zarr", spacing=(0.5, 0.6, 0.7), origin=(1.0, 2.0, 3.0), chunks=32,
                          levels=3, zarr_format=zarr_format)
    a, b = open_zarr(blocks), open_zarr(dask)
    assert [lv.shape for lv in a.levels] == [(90, 90, 90), (45, 45, 45), (22, 22, 22)]
    assert a.levels == [lv.__class__(lv.name, lv.shape, lv.chunks, lv.spacing, lv.origin) for lv in b.levels]
    for level in range(3):
        np.testing.assert_array_equal(a.zarr_array(level)[...], b.zarr_array(level)[...])
    np.testing.assert_array_equal(a.chunk_range(), b.chunk_range())
    assert a.metadata["value_range"] == b.metadata["value_range"] == [float(whole.min()), float(whole.max())]
    assert seen == sorted(seen) and seen[-1] == 1.0


def test_block_writer_refuses_bad_input(tmp_path):
    with pytest.raises(ValueError, match="3D shape"):
        write_ome_zarr_blocks(partial(_ramp_block, 8), (8, 8), np.uint16, tmp_path / "x.zarr")
    with pytest.raises(ValueError, match="workers"):
        write_ome_zarr_blocks(partial(_ramp_block, 8), (8, 8, 8), np.uint16, tmp_path / "x.zarr", workers=0)
    with pytest.raises(ValueError, match="returned shape"):
        write_ome_zarr_blocks(_fixed_block, (9, 9, 9), np.uint16, tmp_path / "y.zarr", chunks=8, workers=1)
    assert not any(tmp_path.iterdir())  # the temporary store is removed
