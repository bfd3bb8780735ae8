"""Our software renderers live in the workbench: progressive frames, comparison views, parallel-only modes."""

from __future__ import annotations

import re

import numpy as np

from .conftest import open_and_wait, wait_ready


def _texture_size(view) -> tuple[int, int]:
    image = view.renderer.GetBackgroundTexture().GetInput()
    width, height, _ = image.GetDimensions()
    return width, height


def test_raymarch_beside_vtk_gpu_previews_while_dragging_and_refines(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "raymarch")
    window.model.set_view_mode(1, "vtk-gpu")
    open_and_wait(qtbot, window, small_ct_file)
    ours = window.views[0]
    full = ours.plotter.ren_win.GetSize()
    assert _texture_size(ours) == tuple(full)
    assert re.search(r"samples per ray, .* of rays terminated early", ours.stats_label.text())

    # A drag: the shared camera turns in small steps; frames arriving meanwhile are previews at a third of the size.
    camera = window.views[1].renderer.GetActiveCamera()
    sizes = []
    for _ in range(12):
        camera.Azimuth(3)
        window.views[1].render(still=False)
        qtbot.wait(30)
        if ours.renderer.GetBackgroundTexture() is not None:
            sizes.append(_texture_size(ours))
    assert any(size[0] < full[0] for size in sizes), sizes
    # At rest it refines to the full size and becomes ready.
    wait_ready(qtbot, window)
    assert _texture_size(ours) == tuple(full)
    assert "preview" not in ours.stats_label.text()


def test_difference_view_shows_the_numbers(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "raymarch-vs-vtk-gpu")
    window.model.set_view_mode(1, "vtk-gpu")
    open_and_wait(qtbot, window, small_ct_file)
    window.model.set_shading(enabled=False)
    wait_ready(qtbot, window)
    text = window.views[0].stats_label.text()
    psnr = float(re.search(r"PSNR ([0-9.]+) dB", text).group(1))
    assert psnr >= 28.0, text  # emission-absorption ray marching agrees with VTK's GPU ray caster
    assert "SSIM" in text and "RMSE" in text
    heatmap = window.views[0].capture()
    assert heatmap.std() > 0  # a heat map, not a blank frame


def test_shear_warp_follows_a_perspective_linked_camera_in_parallel(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "shear-warp")
    window.model.set_view_mode(1, "vtk-cpu")
    open_and_wait(qtbot, window, small_ct_file)
    assert not window.views[1].renderer.GetActiveCamera().GetParallelProjection()
    image = window.views[0].capture()
    assert image.mean() > 3 and "voxels composited" in window.views[0].stats_label.text()


def test_slicing_modes_run_live(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "slicing")
    window.model.set_view_mode(1, "slicing-axis")
    open_and_wait(qtbot, window, small_ct_file)
    for view in window.views[:2]:
        assert "slices" in view.stats_label.text()
        assert view.capture().mean() > 3
    window.views[0].renderer.GetActiveCamera().Azimuth(50)
    window.views[0].render(still=False)
    wait_ready(qtbot, window)
    assert np.isfinite(float(re.search(r"slices ([0-9.]+)", window.views[1].stats_label.text()).group(1)))


def test_marching_cubes_and_its_distance_to_flying_edges(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "marching-cubes")
    window.model.set_view_mode(1, "marching-cubes-vs-flying-edges")
    open_and_wait(qtbot, window, small_ct_file)
    assert "triangles" in window.views[0].stats_label.text()
    text = window.views[1].stats_label.text()
    hausdorff = float(re.search(r"Hausdorff ([0-9.e+-]+) mm", text).group(1))
    assert hausdorff < 0.05  # the same isosurface up to how each method places vertices where samples equal iso
    assert window.views[1].pipeline.content.scalar_bar is not None and window.views[1].capture().mean() > 3
