"""Tetrahedral meshes in the window: the stuffing view beside VTK's clipped tetrahedra, the clip plane dragged and
written back as the views' options, the angle histograms drawn in the views."""

from __future__ import annotations

import numpy as np

from .conftest import open_and_wait, wait_ready


def _histograms(view):
    return [prop for prop in view.pipeline.content.histograms]


def test_stuffing_beside_vtk_clip_tets_with_a_dragged_plane_and_histograms(qtbot, window, small_ct_file):
    window.model.set_layout("1x2")
    window.model.set_view_mode(0, "stuffing")
    window.model.set_view_mode(1, "vtk-clip-tets")
    open_and_wait(qtbot, window, small_ct_file, timeout=300_000)
    ours, theirs = window.views[0], window.views[1]
    for view in (ours, theirs):
        assert view.clip_plane.enabled  # the plane widget is on for modes that clip
        histograms = _histograms(view)
        assert histograms and all(view.renderer.HasViewProp(actor) for actor in histograms)
        assert "tetrahedra" in view.stats_label.text() and "degrees" in view.stats_label.text()
    quality = ours.pipeline.content.stats
    assert 10.7 <= quality["min_dihedral_deg"] and quality["max_dihedral_deg"] <= 164.8
    assert theirs.pipeline.content.stats["min_dihedral_deg"] < 10.7  # VTK's clipped voxels keep slivers

    # The histogram is drawn: its corner of the picture is not the background.
    image = ours.capture()
    height = image.shape[0]
    width, tall = ours.pipeline.content.histograms[0].histogram_size
    corner = image[height - tall + 5:height - 5, 5:width - 5]
    assert corner.mean() > 100  # a white figure with blue bars on a black view

    # Drag the plane (what the widget does while the mouse moves, then on release).
    before = ours.pipeline.content.clipped.shown_cells()
    bounds = np.asarray(ours.pipeline.content.bounds())
    origin = np.array([bounds[0] + 0.3 * (bounds[1] - bounds[0]), 0.5 * (bounds[2] + bounds[3]),
                       0.5 * (bounds[4] + bounds[5])])
    ours.clip_plane.set_plane(origin, (1.0, 0.0, 0.0))
    wait_ready(qtbot, window, timeout=300_000)
    options = window.model.view_options[0]
    np.testing.assert_allclose([float(v) for v in options["clip_origin"].split()], origin, atol=1e-3)
    np.testing.assert_allclose([float(v) for v in options["clip_normal"].split()], (1.0, 0.0, 0.0), atol=1e-6)
    assert ours.pipeline.options["clip_origin"] == options["clip_origin"]
    after = ours.pipeline.content.clipped.shown_cells()
    assert 0 < after < before  # only the right 30 % stays
    assert ours.clip_plane.enabled

    # A mode that does not clip hides the widget.
    window.model.set_view_mode(0, "flying-edges")
    wait_ready(qtbot, window, timeout=300_000)
    assert not ours.clip_plane.enabled
