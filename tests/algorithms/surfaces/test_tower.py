"""The tower algorithm and the hybrid (source 000): equivalence with the baseline, strip structure, orientation,
identical renders, memory accounting, VTK's strip generator, filters and errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from vtkmodules.util import numpy_support

from algorithms.common.progress import OperationCancelled
from algorithms.common.vtk_bridge import image_from_array, run_algorithm
from algorithms.compare.voxel_surfaces import (
    face_set,
    memory_usage,
    same_faces,
    strip_triangles,
    stripper_memory,
    surface_face_set,
)
from algorithms.datasets.volumes import FAMILIES, family
from algorithms.references.vtk_surfaces import vtk_stripper
from algorithms.surfaces.tower import (
    STRIP_BOTTOM,
    STRIP_CIRCUMFERENCE,
    STRIP_TOP,
    HybridFilter,
    TowerFilter,
    TowerStrips,
    hybrid,
    tower_strips,
)
from algorithms.surfaces.voxel_faces import voxel_faces

from .test_voxel_faces import ORIGIN, SPACING, colin27, signed_volume


def assert_same_surface(*surfaces):
    reference = surface_face_set(surfaces[0])
    assert reference.ok, reference.defects
    for surface in surfaces[1:]:
        equal, report = same_faces(reference, surface)
        assert equal, report


def loops_per_slice(model: np.ndarray) -> np.ndarray:
    """Boundary loops of each slice, counted independently of the tower: 4-connected clusters plus their holes.

    With 4-connected solid, the empty space is 8-connected; holes are the 8-connected empty regions of the slice
    (padded with empty space) other than the outside.
    """
    four = ndimage.generate_binary_structure(2, 1)
    eight = ndimage.generate_binary_structure(2, 2)
    counts = []
    for layer in model:
        clusters = ndimage.label(layer, structure=four)[1]
        empty_regions = ndimage.label(~np.pad(layer, 1), structure=eight)[1]
        counts.append(clusters + empty_regions - 1)
    return np.array(counts)


def runs(rows: np.ndarray) -> int:
    """Maximal runs of True along the last axis."""
    padded = np.pad(rows.astype(np.int8), [(0, 0)] * (rows.ndim - 1) + [(1, 0)])
    return int((np.diff(padded, axis=-1) == 1).sum())


# --------------------------------------------------------------------------------------------------------------
# Exact structure on small cases
# --------------------------------------------------------------------------------------------------------------
def test_single_voxel_is_one_loop_one_top_one_bottom():
    strips = tower_strips(np.ones((1, 1, 1), dtype=bool), spacing=(2.0, 2.0, 2.0))
    assert strips.kinds.tolist() == [STRIP_CIRCUMFERENCE, STRIP_BOTTOM, STRIP_TOP]
    assert strips.lengths.tolist() == [10, 4, 4]
    assert strips.n_triangles == 12
    loop = strips.points[:10]
    np.testing.assert_array_equal(loop[0::2, 2], -1.0)  # b0, b1, ...: bottom of the layer
    np.testing.assert_array_equal(loop[1::2, 2], 1.0)
    np.testing.assert_array_equal(loop[:2], loop[-2:])  # closed by repeating b0, t0
    # Top: (x0, y+), (x0, y-), (x1, y+), (x1, y-); bottom: the pairs swapped.
    np.testing.assert_array_equal(strips.points[14:18], [[-1, 1, 1], [-1, -1, 1], [1, 1, 1], [1, -1, 1]])
    np.testing.assert_array_equal(strips.points[10:14], [[-1, -1, -1], [-1, 1, -1], [1, -1, -1], [1, 1, -1]])
    assert_same_surface(voxel_faces(np.ones((1, 1, 1), dtype=bool), spacing=(2.0, 2.0, 2.0)), strips)


def test_reversing_an_even_strip_would_not_flip_it():
    """Why bottom runs swap each pair instead of reversing the strip (see the module notes)."""
    strips = tower_strips(np.ones((1, 1, 1), dtype=bool))
    top = strips.points[14:18]
    ids = np.arange(4)
    as_written = face_set(top, strips=(np.array([0, 4]), ids))
    reversed_strip = face_set(top, strips=(np.array([0, 4]), ids[::-1]))
    pairs_swapped = face_set(top, strips=(np.array([0, 4]), ids[[1, 0, 3, 2]]))
    assert as_written.faces[:, 4].tolist() == [1]
    assert reversed_strip.faces[:, 4].tolist() == [1]
    assert pairs_swapped.faces[:, 4].tolist() == [-1]


@pytest.mark.parametrize(
    ("layer", "loops"),
    [
        # a ring around a hole: outer boundary + hole
        (["#####", "#...#", "#.#.#", "#...#", "#####"], 3),
        # a hole touching the outside at a corner: with 4-connected solid it is not a hole; one loop that
        # passes the pinch corner twice
        ([".##", "#.#", "###"], 1),
        # two voxels touching diagonally (a pinch point): two clusters
        (["#.", ".#"], 2),
        # a checkerboard: every solid voxel is its own cluster
        (["#.#.", ".#.#", "#.#.", ".#.#"], 8),
        # a spiral
        (["#####", "....#", "###.#", "#...#", "#####"], 1),
    ],
)
def test_pinch_points_and_holes(layer, loops):
    model = np.array([[[c == "#" for c in row] for row in layer]])
    model = np.concatenate([model, model[:, ::-1], model[:, :, ::-1]])  # three slices with different rows
    strips = tower_strips(model, spacing=SPACING, origin=ORIGIN)
    circumferences = strips.kinds == STRIP_CIRCUMFERENCE
    assert circumferences.sum() == 3 * loops
    assert (loops_per_slice(model) == loops).all()
    assert_same_surface(voxel_faces(model, spacing=SPACING, origin=ORIGIN), strips)


@pytest.mark.parametrize("name", FAMILIES)
def test_strip_counts_follow_loops_and_runs(name):
    model = family(name, 13, seed=7)
    strips = tower_strips(model)
    kinds = strips.kinds
    assert (kinds == STRIP_CIRCUMFERENCE).sum() == loops_per_slice(model).sum()
    below = np.concatenate([np.zeros_like(model[:1]), model])
    above = np.concatenate([model, np.zeros_like(model[:1])])
    assert (kinds == STRIP_TOP).sum() == runs(below & ~above)
    assert (kinds == STRIP_BOTTOM).sum() == runs(above & ~below)
    # 2 vertices per face plus 2 per strip: the loop closure or the run's first edge.
    faces = voxel_faces(model).n_faces
    assert strips.n_vertices == 2 * faces + 2 * strips.n_strips
    assert np.all(strips.lengths % 2 == 0) and np.all(strips.lengths >= 4)


def test_circumference_strips_walk_vertical_edges_around_a_closed_loop():
    strips = tower_strips(family("spheres", 14, seed=2), spacing=SPACING, origin=ORIGIN)
    for s in np.flatnonzero(strips.kinds == STRIP_CIRCUMFERENCE)[:50]:
        loop = strips.points[strips.offsets[s] : strips.offsets[s + 1]].astype(np.float64)
        bottom, top = loop[0::2], loop[1::2]
        np.testing.assert_array_equal(bottom[:, :2], top[:, :2])  # vertical edges
        assert np.allclose(top[:, 2] - bottom[:, 2], SPACING[2])
        np.testing.assert_array_equal(loop[:2], loop[-2:])
        steps = np.abs(np.diff(bottom[:, :2], axis=0)) / SPACING[:2]
        assert np.allclose(np.sort(steps, axis=1), [0.0, 1.0])  # one voxel edge along x or y at a time


# --------------------------------------------------------------------------------------------------------------
# Equivalence with the baseline (source 000, section 7) and orientation
# --------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", FAMILIES)
@pytest.mark.parametrize("seed", range(4))
def test_tower_and_hybrid_draw_the_baseline_faces(name, seed):
    model = family(name, 15, seed=seed)
    baseline = voxel_faces(model, spacing=SPACING, origin=ORIGIN)
    strips = tower_strips(model, spacing=SPACING, origin=ORIGIN)
    assert strips.n_triangles == len(baseline.triangles)
    assert_same_surface(baseline, strips, hybrid(strips), hybrid(strips, max_strip_vertices=0),
                        hybrid(strips, max_strip_vertices=10**6))


@pytest.mark.parametrize("shape", [(1, 1, 7), (7, 1, 1), (1, 6, 1), (3, 4, 5)])
def test_thin_and_flat_volumes(shape):
    model = np.random.default_rng(sum(shape)).random(shape) < 0.6
    assert_same_surface(voxel_faces(model), tower_strips(model), hybrid(model))


def test_tower_vertices_are_bit_identical_to_baseline_corners():
    model = family("scatter-20", 12, seed=3)
    baseline = voxel_faces(model, spacing=SPACING, origin=ORIGIN)
    strips = tower_strips(model, spacing=SPACING, origin=ORIGIN)
    np.testing.assert_array_equal(np.unique(strips.points, axis=0), np.unique(baseline.points, axis=0))


@pytest.mark.parametrize("name", ["spheres", "scatter-50", "pillars-20"])
def test_strips_enclose_the_solid_volume(name):
    model = family(name, 14, seed=5)
    strips = tower_strips(model, spacing=SPACING, origin=ORIGIN)
    triangles = strip_triangles(strips.offsets, np.arange(strips.n_vertices))
    expected = model.sum() * np.prod(SPACING)
    assert signed_volume(strips.points, triangles) == pytest.approx(expected, rel=1e-5)


def test_ct_phantom_bone(ct_phantom):
    volume = ct_phantom
    options = {"threshold": 300.0, "spacing": volume.spacing, "origin": volume.origin}
    baseline = voxel_faces(volume.array, **options)
    strips = tower_strips(volume.array, **options)
    assert strips.n_triangles == len(baseline.triangles) > 2000
    assert strips.n_vertices < len(baseline.points)
    assert_same_surface(baseline, strips, hybrid(volume.array, **options))


def test_colin27_crop():
    crop = colin27()[60:108, 80:136, 66:114]
    assert_same_surface(voxel_faces(crop, threshold=70), tower_strips(crop, threshold=70), hybrid(crop, threshold=70))


# --------------------------------------------------------------------------------------------------------------
# Identical flat-shaded renders with back-face culling (winding errors would show as holes)
# --------------------------------------------------------------------------------------------------------------
def render(polydata, azimuth: float, elevation: float) -> np.ndarray:
    from vtkmodules.vtkRenderingCore import (
        vtkActor,
        vtkPolyDataMapper,
        vtkRenderer,
        vtkRenderWindow,
        vtkWindowToImageFilter,
    )
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 - registers the OpenGL back end

    mapper = vtkPolyDataMapper()
    mapper.SetInputData(polydata)
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetInterpolationToFlat()
    actor.GetProperty().BackfaceCullingOn()
    renderer = vtkRenderer()
    renderer.AddActor(actor)
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetMultiSamples(0)
    window.SetSize(160, 160)
    window.AddRenderer(renderer)
    renderer.ResetCamera()
    renderer.GetActiveCamera().Azimuth(azimuth)
    renderer.GetActiveCamera().Elevation(elevation)
    renderer.GetActiveCamera().OrthogonalizeViewUp()
    renderer.ResetCameraClippingRange()
    window.Render()
    grabber = vtkWindowToImageFilter()
    grabber.SetInput(window)
    grabber.ReadFrontBufferOff()
    grabber.Update()
    pixels = numpy_support.vtk_to_numpy(grabber.GetOutput().GetPointData().GetScalars()).copy()
    window.Finalize()
    return pixels


@pytest.mark.parametrize("name", ["spheres", "pillars-50", "worst-case"])
def test_renders_are_pixel_identical(name):
    model = family(name, 10, seed=1)
    baseline = voxel_faces(model, spacing=SPACING)
    strips = tower_strips(model, spacing=SPACING)
    inward = TowerStrips(strips.points.reshape(-1, 2, 3)[:, ::-1].reshape(-1, 3).copy(), strips.offsets,
                            strips.kinds, strips.spacing, strips.origin)  # every pair swapped: faces inward
    for azimuth, elevation in ((30, 20), (200, -50), (100, 75)):
        reference = render(baseline.to_polydata(), azimuth, elevation)
        background = np.all(reference == reference[0], axis=1)
        assert 0.02 < 1 - background.mean() < 0.98  # the model fills part of the image
        np.testing.assert_array_equal(render(strips.to_polydata(), azimuth, elevation), reference)
        np.testing.assert_array_equal(render(hybrid(strips).to_polydata(), azimuth, elevation), reference)
        assert np.any(render(inward.to_polydata(), azimuth, elevation) != reference)  # the test can fail


# --------------------------------------------------------------------------------------------------------------
# Hybrid and memory accounting (source 000, sections 6.3 and 9.1)
# --------------------------------------------------------------------------------------------------------------
def test_memory_of_a_single_voxel():
    model = np.ones((1, 1, 1), dtype=bool)
    baseline = memory_usage(voxel_faces(model))
    assert (baseline.vertices, baseline.indices, baseline.strips, baseline.draw_calls) == (24, 36, 0, 1)
    assert (baseline.total_bytes(16), baseline.total_bytes(32)) == (24 * 12 + 72, 24 * 12 + 144)
    tower = memory_usage(tower_strips(model))
    assert (tower.vertices, tower.indices, tower.strips, tower.draw_calls, tower.triangles) == (18, 0, 3, 3, 12)
    assert tower.total_bytes(16) == tower.total_bytes(32) == 216
    everything = memory_usage(hybrid(model))  # L = 10: all three strips converted
    assert (everything.vertices, everything.indices, everything.strips, everything.draw_calls) == (24, 36, 0, 1)
    caps_only = memory_usage(hybrid(model, max_strip_vertices=4))  # top and bottom converted, the loop kept
    assert (caps_only.vertices, caps_only.indices, caps_only.strips, caps_only.draw_calls) == (18, 12, 1, 2)
    # What VTK uploads: float32 points plus three 32-bit indices per triangle, strips decomposed.
    assert (baseline.vtk_upload_bytes, tower.vtk_upload_bytes) == (24 * 12 + 12 * 12, 18 * 12 + 12 * 12)
    with pytest.raises(ValueError, match="16 or 32"):
        baseline.index_bytes(8)


@pytest.mark.parametrize("limit", [0, 4, 6, 10, 30])
def test_hybrid_splits_strips_at_the_limit(limit):
    strips = tower_strips(family("pillars-20", 16, seed=2))
    surface = hybrid(strips, max_strip_vertices=limit)
    short = strips.lengths <= limit
    assert np.all(surface.strips.lengths > limit)
    assert surface.strips.n_strips == (~short).sum()
    assert len(surface.triangles) == 2 * ((strips.lengths[short] - 2) // 2).sum()
    assert surface.n_triangles == strips.n_triangles
    assert len(surface.points) == 2 * len(surface.triangles)
    usage = memory_usage(surface)
    assert usage.vertices == strips.n_vertices - strips.lengths[short].sum() + len(surface.points)
    assert_same_surface(strips, surface)


def test_hybrid_from_volume_equals_hybrid_from_strips():
    model = family("spheres", 16, seed=3)
    direct = hybrid(model, spacing=SPACING, origin=ORIGIN)
    staged = hybrid(tower_strips(model, spacing=SPACING, origin=ORIGIN))
    np.testing.assert_array_equal(direct.points, staged.points)
    np.testing.assert_array_equal(direct.triangles, staged.triangles)
    np.testing.assert_array_equal(direct.strips.points, staged.strips.points)


def test_vtk_stripper_covers_the_faces_but_may_flip_winding():
    """vtkStripper (after merging points) covers every face exactly once, but where edges are shared by four faces
    (voxels touching along an edge) it can join triangles across them with their winding flipped."""
    model = family("scatter-50", 8, seed=2)
    baseline = voxel_faces(model)
    stripped = vtk_stripper(baseline)
    covered = surface_face_set(stripped)
    assert {kind: n for kind, n in covered.defects.items() if n and kind != "faces with mixed winding"} == {}
    by_place = {tuple(row[:4]) for row in surface_face_set(baseline).faces}
    assert {tuple(row[:4]) for row in covered.faces} <= by_place
    assert len(covered) + covered.defects["faces with mixed winding"] == len(by_place)
    indexed, deindexed = stripper_memory(stripped)
    assert indexed.triangles == deindexed.triangles == len(baseline.triangles)
    assert indexed.vertices == stripped.GetNumberOfPoints() < len(baseline.points)
    assert deindexed.indices == 0 and deindexed.vertices == indexed.indices


def test_vtk_stripper_keeps_a_manifold_surface_outward():
    box = np.zeros((6, 7, 8), dtype=bool)
    box[1:5, 2:6, 1:7] = True
    baseline = voxel_faces(box)
    stripped = vtk_stripper(baseline)
    a, b, c = 6, 4, 4  # voxels along x, y, z
    assert stripped.GetNumberOfPoints() == (a + 1) * (b + 1) * (c + 1) - (a - 1) * (b - 1) * (c - 1)  # merged
    assert_same_surface(baseline, stripped)


# --------------------------------------------------------------------------------------------------------------
# Filters, progress, errors
# --------------------------------------------------------------------------------------------------------------
def test_filters_honour_geometry_and_options(ct_phantom):
    volume = ct_phantom
    image = image_from_array(volume.array, volume.spacing, volume.origin)
    geometry = {"spacing": volume.spacing, "origin": volume.origin}
    tower_filter = TowerFilter()
    tower_filter.SetInputDataObject(0, image)
    tower_filter.SetThreshold(300.0)
    tower_output = run_algorithm(tower_filter)
    core = tower_strips(volume.array, threshold=300.0, **geometry)
    assert tower_output.GetNumberOfStrips() == core.n_strips and tower_output.GetNumberOfPolys() == 0
    hybrid_filter = HybridFilter()
    hybrid_filter.SetInputDataObject(0, image)
    hybrid_filter.SetThreshold(300.0)
    hybrid_filter.SetMaxStripVertices(12)
    hybrid_output = run_algorithm(hybrid_filter)
    core_hybrid = hybrid(core, max_strip_vertices=12)
    assert hybrid_output.GetNumberOfPolys() == len(core_hybrid.triangles)
    assert hybrid_output.GetNumberOfStrips() == core_hybrid.strips.n_strips
    assert_same_surface(
        voxel_faces(volume.array, threshold=300.0, **geometry),
        surface_face_set(tower_output, **geometry),
        surface_face_set(hybrid_output, **geometry),
    )


def test_hybrid_filter_setter():
    vtk_filter = HybridFilter()
    assert vtk_filter.GetMaxStripVertices() == 10
    before = vtk_filter.GetMTime()
    vtk_filter.SetMaxStripVertices(10)
    assert vtk_filter.GetMTime() == before
    vtk_filter.SetMaxStripVertices(4)
    assert vtk_filter.GetMTime() > before
    with pytest.raises(ValueError, match=">= 0"):
        vtk_filter.SetMaxStripVertices(-1)


def test_progress_and_cancellation():
    model = family("spheres", 24)
    seen = []
    tower_strips(model, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) >= 2

    def cancel(fraction):
        raise OperationCancelled("stop")

    with pytest.raises(OperationCancelled):
        tower_strips(model, progress=cancel)
    vtk_filter = TowerFilter()
    vtk_filter.SetInputDataObject(0, image_from_array(model.astype(np.uint8)))
    with pytest.raises(OperationCancelled):
        run_algorithm(vtk_filter, progress=cancel)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"max_strip_vertices": -1}, "must be >= 0"),
        ({"max_strip_vertices": 2.5}, "must be an integer"),
        ({"max_strip_vertices": True}, "must be an integer"),
        ({"threshold": 0.5}, "the strips already carry their geometry"),
        ({"spacing": (1.0, 1.0, 1.0)}, "the strips already carry their geometry"),
    ],
)
def test_hybrid_invalid_options_raise(arguments, message):
    strips = tower_strips(np.ones((2, 2, 2), dtype=bool))
    with pytest.raises(ValueError, match=message):
        hybrid(strips, **arguments)


def test_hybrid_rejects_strips_that_are_not_tower_strips():
    odd = TowerStrips(np.zeros((5, 3), np.float32), np.array([0, 5]), np.zeros(1, np.int8), (1.0,) * 3, (0.0,) * 3)
    with pytest.raises(ValueError, match="even number of vertices"):
        hybrid(odd)


@pytest.mark.parametrize(
    ("volume", "options", "message"),
    [
        (np.ones((4, 4)), {"threshold": 1}, "expected a 3D volume"),
        (np.ones((2, 2, 2)), {}, "needs a threshold"),
        (np.ones((2, 2, 2), dtype=bool), {"spacing": (1.0, -1.0, 1.0)}, "spacing must be three positive"),
    ],
)
def test_tower_invalid_input_raises(volume, options, message):
    with pytest.raises(ValueError, match=message):
        tower_strips(volume, **options)
    with pytest.raises(ValueError, match=message):
        hybrid(volume, **options)
