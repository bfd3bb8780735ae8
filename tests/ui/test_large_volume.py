"""The window opens an OME-Zarr pyramid too large for the memory budget at the finest level that fits (issue 19).

Refining the region in view when zoomed is not implemented yet (docs/large-volumes.md, "Not yet done")."""

from __future__ import annotations

import time

import numpy as np
import pytest

from app.io.zarr import write_ome_zarr

from .conftest import open_and_wait

pytestmark = pytest.mark.gui


def test_window_opens_a_pyramid_at_the_level_that_fits_the_budget(qtbot, window, tmp_path, monkeypatch):
    import app.io.zarr as zarr_io

    z, y, x = np.ogrid[:160, :192, :256]
    array = (1000 + 800 * np.sin(x / 20.0) * np.cos(y / 25.0) * np.sin(z / 15.0)).astype(np.uint16)
    store = write_ome_zarr(array, tmp_path / "large.zarr", spacing=(0.2, 0.2, 0.3), chunks=64)
    # The budget as if this volume were 1024^3 on a 1 GiB budget: only level 1 (128 x 96 x 80) fits.
    monkeypatch.setattr(zarr_io, "DEFAULT_BUDGET", 128 * 96 * 80 * 2)
    started = time.perf_counter()
    open_and_wait(qtbot, window, store)
    seconds = time.perf_counter() - started
    volume = window.model.volume
    assert volume.dimensions == (128, 96, 80)
    np.testing.assert_allclose(volume.spacing, (0.4, 0.4, 0.6))
    assert volume.metadata["level"] == 1
    assert any("opened pyramid level 1" in warning for warning in volume.metadata["warnings"])
    print(f"opened level 1 of the pyramid and drew every view in {seconds:.1f} s")
