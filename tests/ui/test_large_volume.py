"""The window opens an OME-Zarr pyramid too large for the view budget at a coarse level, shows the region in view
from a finer level when zoomed in, and the coarse level again when zoomed out (issue 19)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from algorithms.common.camera import Camera
from app.io.zarr import open_zarr, write_ome_zarr
from app.volume import Volume

from .conftest import open_and_wait, wait_ready

pytestmark = pytest.mark.gui

ROTATED = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@pytest.fixture
def pyramid(tmp_path, monkeypatch):
    """256^3 uint16, 3 levels (256, 128, 64), with budgets as if it were a 2048^3 store on the default budgets:
    only level 2 fits the coarse budget."""
    import app.pyramid_view as pyramid_view

    z, y, x = np.ogrid[:256, :256, :256]
    array = (1000 + 800 * np.sin(x / 20.0) * np.cos(y / 25.0) * np.sin(z / 15.0)).astype(np.uint16)
    store = write_ome_zarr(array, tmp_path / "large.zarr", spacing=(0.2, 0.25, 0.3), origin=(-10.0, 5.0, 2.0),
                           direction=ROTATED, chunks=64, levels=3)
    monkeypatch.setattr(pyramid_view, "COARSE_BUDGET", 64**3 * 2)
    monkeypatch.setattr(pyramid_view, "REGION_BUDGET", 2 << 20)  # < level 1 whole (4 MiB)
    return store, array


def _zoom(window, volume: Volume, ijk, half_height_mm: float) -> None:
    """Point the (linked) camera along +j at sample ``ijk``, parallel projection, ``half_height_mm`` half height."""
    focal = volume.index_to_world(np.asarray(ijk, float))
    forward = volume.direction @ np.array([0.0, 1.0, 0.0])
    up = volume.direction @ np.array([0.0, 0.0, 1.0])
    camera = Camera(tuple(focal - 300.0 * forward), tuple(focal), tuple(up), 30.0, True, half_height_mm)
    camera.apply_to_vtk(window.views[window.active_view].renderer.GetActiveCamera())


def test_window_opens_coarse_refines_when_zoomed_and_goes_back(qtbot, window, pyramid):
    store, array = pyramid
    chunked = open_zarr(store)
    started = time.perf_counter()
    open_and_wait(qtbot, window, store)
    seconds = time.perf_counter() - started
    coarse_item = window.model.item
    coarse = coarse_item.volume
    assert coarse.dimensions == (64, 64, 64) and coarse.metadata["level"] == 2
    np.testing.assert_allclose(coarse.spacing, (0.8, 1.0, 1.2))
    assert any("opened pyramid level 2" in w for w in coarse.metadata["warnings"])
    visible = [view for view in window.views[: window.model.view_count] if view.isVisible()]
    assert visible and all(view.item is coarse_item for view in visible)
    print(f"opened level 2 of the pyramid and drew every view in {seconds:.1f} s")

    # Zoom in on a small part: the views get a level-0 region that lines up with the full-resolution volume.
    level0 = Volume(array, chunked.spacing, chunked.origin, chunked.direction)
    with qtbot.waitSignal(window.pyramid.region_shown, timeout=60_000) as shown:
        _zoom(window, level0, (120, 128, 100), 6.0)
    region_item = shown.args[0]
    assert region_item is not coarse_item
    plan = window.pyramid.plan
    assert plan is not None and plan.level == 0
    (k0, j0, i0), (k1, j1, i1) = plan.start, plan.stop
    # +-6 mm around the focal point: 30 samples of 0.2 mm along i, 20 of 0.3 mm along k; all of j (the depth).
    assert abs(i0 - 90) <= 2 and abs(i1 - 150) <= 3 and abs(k0 - 80) <= 2 and abs(k1 - 120) <= 3
    assert (j0, j1) == (0, 256)
    region = region_item.volume
    np.testing.assert_array_equal(region.array, array[k0:k1, j0:j1, i0:i1])
    np.testing.assert_allclose(region.spacing, (0.2, 0.25, 0.3))
    np.testing.assert_allclose(region.index_to_world([3, 4, 5]), level0.index_to_world([i0 + 3, j0 + 4, k0 + 5]),
                               atol=1e-9)
    assert region.value_range == coarse.value_range  # the same colours for the same values
    wait_ready(qtbot, window)
    assert all(view.item is region_item for view in visible)
    assert window.model.item is coarse_item  # the scene still holds the volume as opened

    # Zoom out: the coarse level again.
    with qtbot.waitSignal(window.pyramid.region_shown, timeout=60_000) as shown:
        _zoom(window, level0, (128, 128, 128), 200.0)
    assert shown.args[0] is coarse_item and window.pyramid.plan is None
    wait_ready(qtbot, window)
    assert all(view.item is coarse_item for view in visible)


def test_closing_the_window_while_a_region_is_read_shows_nothing_afterwards(qtbot, window, pyramid, monkeypatch):
    """A read still running (or the settle timer still pending) when the window closes must not reach its views:
    they are shut down, and drawing into them would touch a released render window."""
    import ui.window_pyramid as window_pyramid

    store, array = pyramid
    chunked = open_zarr(store)
    open_and_wait(qtbot, window, store)
    level0 = Volume(array, chunked.spacing, chunked.origin, chunked.direction)
    started = []
    real_read = window_pyramid.read_region

    def slow_read(*args, progress=None, **kwargs):
        started.append(True)
        time.sleep(0.5)  # the window closes meanwhile
        return real_read(*args, progress=progress, **kwargs)

    monkeypatch.setattr(window_pyramid, "read_region", slow_read)
    shown = []
    window.pyramid.region_shown.connect(shown.append)
    _zoom(window, level0, (120, 128, 100), 6.0)
    qtbot.waitUntil(lambda: bool(started), timeout=10_000)  # the settle timer fired and the read began
    window.close()
    _zoom(window, level0, (60, 128, 60), 6.0)  # a camera event after closing starts nothing
    qtbot.wait(1500)
    assert shown == []
    assert window.pyramid.chunked is None and not window.pyramid._timer.isActive()
    assert all(view._shut_down for view in window.views)
