"""Legible, fixed-meaning legends of the comparison views (issue 17, item 6).

The distance view's colours and colour bar come from a tolerance (default a tenth of the smallest voxel spacing,
settable as the mode's ``tolerance`` option), not from the distances found: marching cubes against flying edges
differ by rounding noise (1e-5 mm), which must show as the calm end of the scale. The image-difference views
get a colour bar on the same principle (``difference_tolerance``, fractions of full scale). Labels are readable:
fixed font size in points, three significant digits.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from vtkmodules.util import numpy_support

from app.datasets import ct_head_phantom
from app.modes import get_mode
from app.modes.comparisons import (DIFFERENCE_TOLERANCE, ImageDifferenceContent, SurfaceDistanceContent,
                                   distance_tolerance, image_difference, surface_distance)
from app.pipeline.headless import RenderSettings, render_item, view_inputs
from app.pipeline.props import LEGEND_FONT_SIZE, difference_colors, distance_actor, distance_colors
from app.scene import VolumeItem


@pytest.fixture(scope="module")
def ct_item():
    return VolumeItem("ct", volume=ct_head_phantom((40, 96, 96), (2.4, 2.4, 4.0)))


def bar_range(bar) -> tuple[float, float]:
    return tuple(bar.GetLookupTable().GetRange())


def test_distance_scale_comes_from_the_tolerance_not_the_data(ct_item):
    result = surface_distance(ct_item, get_mode("marching-cubes"), get_mode("flying-edges"), 300.0)
    distances = numpy_support.vtk_to_numpy(result.polydata.GetPointData().GetArray("distance_mm"))
    assert result.stats["hausdorff_mm"] < 1e-3  # rounding noise only
    tolerance = distance_tolerance({}, ct_item.volume)
    assert tolerance == pytest.approx(0.24)  # a tenth of the smallest spacing, 2.4 mm
    actor, bar = distance_actor(result.polydata, ct_item.local_to_world, "distance_mm", tolerance_mm=tolerance)
    assert bar_range(bar) == (0.0, pytest.approx(0.48))
    assert actor.GetMapper().GetScalarRange() == (0.0, pytest.approx(0.48))
    # Every vertex is within the tolerance: all of them are drawn on the blue half, none red.
    colors = distance_colors(tolerance)
    rgb = np.array([colors.GetColor(float(d)) for d in distances[:: max(1, len(distances) // 500)]])
    assert np.all(rgb[:, 2] > rgb[:, 0])
    assert colors.GetColor(tolerance) == pytest.approx((0.87, 0.87, 0.87))
    assert colors.GetColor(5.0) == pytest.approx((0.71, 0.02, 0.15))  # beyond the bar: the top colour
    assert distance_tolerance({"tolerance": 0.05}, ct_item.volume) == 0.05
    with pytest.raises(ValueError, match="positive distance in mm"):
        distance_actor(result.polydata, ct_item.local_to_world, "distance_mm", tolerance_mm=0.0)


def test_colour_bars_are_readable(ct_item):
    result = surface_distance(ct_item, get_mode("marching-cubes"), get_mode("flying-edges"), 300.0)
    _, bar = distance_actor(result.polydata, ct_item.local_to_world, "distance_mm", tolerance_mm=0.094)
    assert bar.GetLabelFormat() == "%.3g" and bar.GetNumberOfLabels() == 5
    assert bar.GetUnconstrainedFontSize()
    assert bar.GetLabelTextProperty().GetFontSize() == LEGEND_FONT_SIZE >= 12
    assert "mm" in bar.GetTitle()
    # The five labels: 0, tol/2, tol, 3 tol/2, 2 tol as three significant digits.
    labels = [bar.GetLabelFormat() % value for value in np.linspace(0.0, 0.188, 5)]
    assert labels == ["0", "0.047", "0.094", "0.141", "0.188"]


def test_distance_view_through_the_pipeline_uses_the_option(ct_item):
    report = render_item(ct_item, RenderSettings(mode=get_mode("marching-cubes-vs-flying-edges"), size=(96, 96),
                                                 options={"tolerance": 0.5}))
    assert report.info["surface"]["tolerance_mm"] == 0.5
    default = render_item(ct_item, RenderSettings(mode=get_mode("marching-cubes-vs-flying-edges"), size=(96, 96)))
    assert default.info["surface"]["tolerance_mm"] == pytest.approx(0.24)


def test_image_difference_scale_comes_from_the_tolerance():
    rng = np.random.default_rng(0)
    reference = rng.integers(0, 256, (32, 32, 3)).astype(np.uint8)
    test = reference.copy()
    test[:16] = np.clip(test[:16].astype(int) + 3, 0, 255)  # 3 grey levels: 0.012 of full scale
    difference = image_difference(test, reference)
    assert difference.numbers["legend_top"] == 2 * DIFFERENCE_TOLERANCE
    # Small differences stay dark instead of being stretched to the brightest colour.
    assert difference.heatmap[:16].mean() < 80 and difference.heatmap[16:].max() < 10
    stretched = image_difference(test, reference, tolerance=0.005)
    assert stretched.heatmap[:16].mean() > difference.heatmap[:16].mean() + 50
    table = difference_colors(0.05)
    assert table.GetRange() == (0.0, 0.1)
    with pytest.raises(ValueError, match="positive fraction"):
        image_difference(test, reference, tolerance=-1.0)


def test_image_difference_view_has_a_colour_bar(ct_item):
    from app.pipeline.jobs import ImmediateRunner
    from app.pipeline.offscreen import OffscreenScene
    from app.pipeline.view import ViewPipeline

    scene = OffscreenScene((96, 96))
    pipeline = ViewPipeline(scene.renderer, ImmediateRunner(), lambda: (96, 96))
    try:
        pipeline.set_inputs(view_inputs(ct_item), get_mode("raymarch-vs-vtk-gpu"), {"difference_tolerance": 0.02})
        scene.render()
        content = pipeline.content
        assert isinstance(content, ImageDifferenceContent)
        bars = [prop for prop in content.props if prop.IsA("vtkScalarBarActor")]
        assert len(bars) == 1 and bar_range(bars[0]) == (0.0, pytest.approx(0.04))
        assert "full" in bars[0].GetTitle() and "scale" in bars[0].GetTitle()
        assert pipeline.last_frame.stats["legend_top"] == pytest.approx(0.04)
        assert get_mode("raymarch-vs-vtk-gpu").option("difference_tolerance").default == DIFFERENCE_TOLERANCE
    finally:
        pipeline.shutdown()
        scene.close()


def test_legend_options_on_the_command_line(tmp_path):
    out = tmp_path / "d.png"
    process = subprocess.run([sys.executable, "-m", "app.cli", "render", "sample", "--mode",
                              "marching-cubes-vs-flying-edges", "--tolerance", "0.2", "--size", "96", "96", "-o", out,
                              "--json"], capture_output=True, text=True, timeout=600)
    assert process.returncode == 0, process.stderr
    assert json.loads(process.stdout)["surface"]["tolerance_mm"] == 0.2
    bad = subprocess.run([sys.executable, "-m", "app.cli", "render", "sample", "--mode", "raymarch", "--tolerance",
                          "0.2", "-o", tmp_path / "e.png"], capture_output=True, text=True, timeout=600)
    assert bad.returncode == 1 and "--tolerance does not apply to mode 'raymarch'" in bad.stderr
    assert isinstance(SurfaceDistanceContent, type)
