"""The workbench's Qt-free model: defaults per volume, validation, and change signals."""

from __future__ import annotations

import numpy as np
import pytest

from app.workbench import WorkbenchModel, default_window_level

from app.datasets import ct_head_phantom


@pytest.fixture
def model():
    model = WorkbenchModel()
    model.set_volume(ct_head_phantom(shape=(22, 52, 52), spacing=(5.0, 5.0, 10.0)))  # the whole head, coarse
    return model


def record(signal):
    seen = []
    signal.connect(lambda *args: seen.append(args))
    return seen


def test_defaults_follow_the_volume(model):
    assert model.iso == 300.0 and model.preset == "ct-bone"
    assert (model.window, model.level) == default_window_level(model.volume) == (400.0, 40.0)
    assert np.allclose(model.cursor, model.volume.centre)


def test_setters_validate_and_emit_only_on_change(model):
    iso = record(model.iso_changed)
    model.set_iso(500)
    model.set_iso(500)
    assert iso == [(500.0,)]
    with pytest.raises(ValueError, match="outside the volume's range"):
        model.set_iso(1e6)
    with pytest.raises(ValueError, match="window must be a positive number"):
        model.set_window_level(0, 40)
    with pytest.raises(ValueError, match="layout must be one of"):
        model.set_layout("3x3")
    with pytest.raises(ValueError, match="unknown render mode 'nope'"):
        model.set_view_mode(0, "nope")
    modes = record(model.view_mode_changed)
    model.set_view_mode(2, "raymarch")
    assert [change[:2] for change in modes] == [(2, "raymarch")]
    assert modes[0][2]["light_samples"] == 8  # the mode's options, resolved


def test_transfer_function_edits(model):
    changes = record(model.transfer_function_changed)
    model.set_opacity_points([(-1024, 0.0), (250, 0.0), (900, 0.5)])
    assert model.transfer_function.opacity_points == ((-1024.0, 0.0), (250.0, 0.0), (900.0, 0.5))
    model.set_color_points([(-1024, 0, 0, 0), (3071, 1, 1, 1)])
    model.set_shading(enabled=False, specular=0.5)
    assert not model.transfer_function.shading.enabled and model.transfer_function.shading.specular == 0.5
    model.set_preset("ct-skin")  # keeps the shading choice
    assert model.transfer_function.name == "ct-skin" and not model.transfer_function.shading.enabled
    assert len(changes) == 4
    with pytest.raises(ValueError, match="opacities must lie in"):
        model.set_opacity_points([(0, 2.0)])


def test_cursor_is_clamped_to_the_volume(model):
    model.set_cursor((1e4, -1e4, 0))
    ijk = model.volume.world_to_index(model.cursor)
    assert np.all(ijk >= -1e-9) and np.all(ijk <= np.asarray(model.volume.dimensions) - 1 + 1e-9)
