"""The window's views are hosts of the shared view pipeline: the same frames as the command line's, every option of
every mode reachable through the options panel, modes registered at run time in the chooser, and our VTK filters'
progress and abort driving the status bar."""

from __future__ import annotations

import time

import numpy as np
import pytest

from app.modes import get_mode, mode_names, register_mode, unregister_mode
from app.pipeline import RenderSettings, render_item

from .conftest import open_and_wait, wait_ready


def _image_modes() -> list[str]:
    """Our software renderers and their comparisons with VTK: the modes whose picture is a frame of their own."""
    return [name for name in mode_names(output=("image", "comparison"))
            if get_mode(name).output == "image" or get_mode(name).test.output == "image"]


@pytest.mark.parametrize("mode", _image_modes())
def test_every_image_mode_draws_the_same_frame_headless_and_in_a_view(qtbot, window, small_ct_file, mode):
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, mode)
    open_and_wait(qtbot, window, small_ct_file)
    view = window.views[0]
    shown = view.pipeline.last_frame.image
    assert shown.shape[:2] == tuple(reversed(view.pipeline.viewport_size())) and shown.std() > 0
    settings = RenderSettings(mode=get_mode(mode), size=view.pipeline.viewport_size(), camera=view.pipeline.camera())
    headless = render_item(view.item, settings)
    assert headless.frame is not None
    np.testing.assert_array_equal(headless.frame, shown)


def test_a_mode_registered_at_run_time_appears_in_the_chooser_with_its_options(qtbot, window, small_ct_file):
    from .._registered_mode import TEST_MODE

    register_mode(TEST_MODE)
    try:
        window.model.set_layout("1x1")
        open_and_wait(qtbot, window, small_ct_file)
        view = window.views[0]
        view.mode_box.set_item(view.item)
        assert "test-shifted-faces" in view.mode_box.names()
        window.model.set_view_mode(0, "test-shifted-faces")
        wait_ready(qtbot, window)
        assert set(view.options_panel.widgets) == {"shift"}
        triangles = view.current_surface().stats["triangles"]
        view.options_panel.widgets["shift"].setValue(400.0)  # as the user types it
        wait_ready(qtbot, window)
        assert window.model.view_options[0] == {"shift": 400.0}
        assert 0 < view.current_surface().stats["triangles"] != triangles
    finally:
        unregister_mode(TEST_MODE.name)


def test_options_panel_sets_scatter_lighting_and_opengl_slicing(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "raymarch")
    window.model.set_view_mode(1, "slicing")
    open_and_wait(qtbot, window, small_ct_file)
    ours, slicing = window.views[0], window.views[1]
    before = ours.pipeline.last_frame.image.copy()

    ours.options_button.click()
    assert ours.options_panel.isVisible()
    lighting = ours.options_panel.widgets["lighting"]
    lighting.setCurrentIndex(lighting.findData("scatter"))
    lighting.activated.emit(lighting.currentIndex())
    ours.options_panel.widgets["light_samples"].setValue(8)
    wait_ready(qtbot, window)
    assert ours.pipeline.options["lighting"] == "scatter" and ours.pipeline.options["light_samples"] == 8
    assert ours.pipeline.content.filter.GetLighting() == "scatter"
    assert ours.pipeline.content.filter.GetLightSamples() == 8
    assert not np.array_equal(ours.pipeline.last_frame.image, before)

    slicing.options_button.click()
    slicing.options_panel.widgets["slices"].setValue(128)
    compositing = slicing.options_panel.widgets["compositing"]
    compositing.setCurrentIndex(compositing.findData("gl"))
    compositing.activated.emit(compositing.currentIndex())
    wait_ready(qtbot, window)
    assert window.model.view_options[1] == {"slices": 128, "compositing": "gl"}
    content = slicing.pipeline.content
    assert type(content).__name__ == "SliceStackContent" and content.stats["slices"] == 128
    assert len(content.stack.actors) > 0 and slicing.capture().mean() > 3


def test_our_filters_progress_reaches_the_status_bar_and_cancel_aborts_them(qtbot, window, tmp_path, monkeypatch):
    """The marching-cubes view runs MarchingCubesFilter; its VTK progress events move the status bar's progress and
    Cancel aborts the filter (its abort flag is set and the extraction stops early)."""
    from algorithms.surfaces.marching_cubes import MarchingCubesFilter
    from app.datasets import sphere_field
    from app.io import save_volume
    from app.volume import Volume

    field = sphere_field((220, 220, 220), 90.0) + 0.05 * np.random.default_rng(1).standard_normal((220, 220, 220))
    path = save_volume(Volume(field.astype(np.float32)), tmp_path / "sphere.nii")
    filters, events = [], []
    original_init = MarchingCubesFilter.__init__

    def record(caller, event):
        events.append((id(caller), caller.GetProgress()))
        # The status bar shows progress on a 200 ms timer (so fast work does not redraw it); on a quiet machine the
        # whole extraction can take less than that, so each report waits a little to let the bar show it.
        time.sleep(0.1)

    def spying_init(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        filters.append(self)
        self.AddObserver("ProgressEvent", record)

    monkeypatch.setattr(MarchingCubesFilter, "__init__", spying_init)
    shown: list[int] = []
    window.progress.valueChanged.connect(shown.append)
    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "marching-cubes")
    open_and_wait(qtbot, window, path, timeout=300_000)
    view = window.views[0]
    by_filter = {}
    for key, fraction in events:
        by_filter.setdefault(key, []).append(fraction)
    view_filter = by_filter[id(filters[-1])]  # the view's extraction (the first may be numba's warm-up)
    assert len(view_filter) > 2 and view_filter == sorted(view_filter) and view_filter[-1] == 1.0
    full = view.current_surface().stats["triangles"]

    assert shown and max(shown) > 0  # the extraction's progress reached the status bar's progress bar
    filters.clear()
    events.clear()
    cancel_at = {}

    def cancel_on_first_progress(caller, event):
        # What the status bar's Cancel button does (window.tasks.cancel_all), at a known point of the extraction: the
        # filter's first progress report above zero.
        if caller.GetProgress() > 0 and not cancel_at:
            cancel_at["fraction"] = caller.GetProgress()
            window.tasks.cancel_all()

    def cancelling_init(self, *args, **kwargs):
        spying_init(self, *args, **kwargs)
        self.AddObserver("ProgressEvent", cancel_on_first_progress)

    monkeypatch.setattr(MarchingCubesFilter, "__init__", cancelling_init)
    window.model.set_iso(-3.0)
    qtbot.waitUntil(lambda: bool(cancel_at) and not view.pipeline.preparing, timeout=60_000)
    running = filters[-1]
    assert view.stats_label.text().startswith("cancelled")
    # It stopped early: VTK's executive reports 1.0 whenever RequestData returns, but the filter's own fractions of the
    # aborted run end where it was cancelled, before those of the full run.
    reached = max(fraction for key, fraction in events if key == id(running) and fraction < 1.0)
    assert reached == cancel_at["fraction"] < max(fraction for fraction in view_filter if fraction < 1.0)
    assert view.current_surface().stats["triangles"] == full  # the previous surface stays


def test_an_operation_adds_a_mesh_beside_the_volume_and_fields_draw_over_the_slices(qtbot, window, small_ct_file):
    import numpy as np

    from app.scene import FieldItem

    window.model.set_layout("1x1")
    window.model.set_view_mode(0, "vtk-gpu")
    open_and_wait(qtbot, window, small_ct_file)
    head = window.model.item
    with qtbot.waitSignal(window.operation_finished, timeout=120_000) as made:
        window.run_operation("extract-surface", items={"volume": head}, options={"method": "flying-edges"})
    mesh = made.args[0]
    assert mesh.kind == "mesh" and window.model.item is head  # the volume stays on show, the mesh beside it
    assert len(window.views[0].pipeline._overlays) == 1

    # A mask on the volume's grid is drawn over the slices.
    mask = (head.volume.array > 300).astype(np.uint8)
    field = FieldItem("bone mask", volume=head.volume.with_array(mask, units="", modality=""), role="mask")
    window.model.scene.add(field)
    axial = window.slice_views["axial"]
    qtbot.waitUntil(lambda: len(axial.overlays) == 1, timeout=30_000)
    assert axial.overlays[0][1] == "mask"
