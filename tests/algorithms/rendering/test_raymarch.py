"""Ray-marching volume renderer: analytic slabs, accelerations that must not change the image, lighting models,
agreement with VTK's ray casters, the VTK filter and every documented error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from algorithms.common.camera import Camera
from algorithms.common.progress import OperationCancelled
from algorithms.common.transfer import TransferTable
from algorithms.common.vtk_bridge import VTKError, image_from_array, run_algorithm
from algorithms.compare.image_metrics import psnr_foreground
from algorithms.datasets.volumes import sphere_field
from algorithms.rendering.raymarch import RaymarchFilter, RaymarchRenderer, raymarch, shading_normals, step_for_samples

COLOUR = (0.9, 0.5, 0.1)


def constant_table(opacity: float, colour=COLOUR, value_range=(0.0, 200.0), unit_distance: float = 1.0):
    """The same colour and opacity (per ``unit_distance`` mm) for every value."""
    rgba = np.array([[*colour, opacity], [*colour, opacity]], dtype=np.float32)
    return TransferTable(rgba, *value_range, unit_distance=unit_distance)


def top_down_camera(centre_xy, parallel_scale: float) -> Camera:
    """A parallel camera looking down -z onto the volume frame's xy plane."""
    x, y = centre_xy
    return Camera(position=(x, y, 100.0), focal_point=(x, y, 0.0), view_up=(0, 1, 0),
                  parallel_projection=True, parallel_scale=parallel_scale)


@pytest.fixture(scope="module")
def slab():
    """A homogeneous block 16 mm deep along z (voxel centres 0..16 mm), 8 x 8 mm across."""
    return np.full((17, 9, 9), 100.0, dtype=np.float32), (1.0, 1.0, 1.0)


# -- analytic ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("step", [0.25, 0.5, 1.0, 2.0, 4.0])
def test_homogeneous_slab_transmits_beer_lambert(slab, step):
    volume, spacing = slab
    opacity, depth = 0.2, 16.0
    sigma = -math.log(1 - opacity)  # per mm (unit distance 1 mm)
    renderer = RaymarchRenderer(volume, spacing, constant_table(opacity), sample_distance=step, early_termination=None)
    result = renderer.render(
        top_down_camera((4, 4), 3.0), 8, 8
    )
    transmittance = 1.0 - result.rgba[..., 3]
    # The opacity correction makes the result independent of the step; float32 tables leave ~1e-6.
    np.testing.assert_allclose(transmittance, math.exp(-sigma * depth), rtol=2e-5)
    # An emission-only slab glows with its colour times its opacity (premultiplied).
    glow = np.multiply(COLOUR, 1 - math.exp(-sigma * depth))
    np.testing.assert_allclose(result.rgba[..., :3], np.broadcast_to(glow, (8, 8, 3)), rtol=2e-5)
    assert result.stats["samples_per_ray"] == depth / step


def test_opacity_applies_per_unit_distance(slab):
    volume, spacing = slab
    opacity, depth, unit_distance = 0.2, 16.0, 2.5
    sigma = -math.log(1 - opacity) / unit_distance  # extinction per mm
    table = constant_table(opacity, unit_distance=unit_distance)
    result = RaymarchRenderer(volume, spacing, table, sample_distance=0.5, early_termination=None).render(
        top_down_camera((4, 4), 3.0), 4, 4
    )
    np.testing.assert_allclose(1.0 - result.rgba[..., 3], math.exp(-sigma * depth), rtol=2e-5)


@pytest.mark.parametrize("step", [0.3, 0.7, 3.0])
def test_sampling_drops_the_last_partial_step_like_vtk(slab, step):
    # Samples at t_in + k * step for k = 1 .. floor(L / step): the depth actually integrated is floor(L/step) steps.
    volume, spacing = slab
    opacity, depth = 0.2, 16.0
    samples = math.floor(depth / step)
    renderer = RaymarchRenderer(volume, spacing, constant_table(opacity), sample_distance=step, early_termination=None)
    result = renderer.render(
        top_down_camera((4, 4), 3.0), 6, 6
    )
    expected = (1 - opacity) ** (samples * step)
    np.testing.assert_allclose(1.0 - result.rgba[..., 3], expected, rtol=2e-5)
    assert result.stats["samples_per_ray"] == samples


def test_a_camera_inside_the_box_starts_its_rays_at_the_camera(slab):
    # Camera at z = 10 mm inside the 16 mm deep block, looking down -z: the central ray crosses 10 mm of it.
    volume, spacing = slab
    opacity, step = 0.2, 0.5
    camera = Camera(position=(4, 4, 10), focal_point=(4, 4, 0), view_up=(0, 1, 0), view_angle=5.0)
    renderer = RaymarchRenderer(volume, spacing, constant_table(opacity), sample_distance=step, early_termination=None)
    result = renderer.render(
        camera, 2, 2
    )
    # The four pixel rays lean by 1.8 degrees: 10 mm / cos(1.8 deg) stays below 10 mm + step, so 20 samples each.
    assert result.stats["samples_per_ray"] == 20
    np.testing.assert_allclose(1.0 - result.rgba[..., 3], (1 - opacity) ** 10.0, rtol=2e-5)


def test_rays_that_miss_the_box_stay_empty(slab):
    volume, spacing = slab
    result = RaymarchRenderer(volume, spacing, constant_table(0.5)).render(top_down_camera((4, 4), 8.0), 32, 32)
    # The box spans x, y in [0, 8] mm; the view spans [-4, 12] mm: a ring of pixels outside sees nothing.
    assert np.all(result.rgba[:, :7] == 0) and np.all(result.rgba[:, -7:] == 0)
    assert np.all(result.rgba[10:22, 10:22, 3] > 0.9)
    assert result.stats["rays"] == 32 * 32
    assert 0 < result.stats["rays_hit"] < 32 * 32


def test_step_for_samples_divides_the_box_diagonal():
    step = step_for_samples((5, 9, 13), (0.5, 1.0, 2.0), 40)
    assert step == pytest.approx(math.sqrt(6.0**2 + 8.0**2 + 8.0**2) / 40)


# -- accelerations ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def phantom_scene(ct_phantom):
    from app.pipeline import default_camera
    from app.transfer import transfer_function_for

    world_camera = default_camera(ct_phantom, azimuth=30, elevation=15)
    camera = world_camera.transformed(np.linalg.inv(ct_phantom.local_to_world))
    return ct_phantom, world_camera, camera, transfer_function_for


@pytest.mark.parametrize("lighting", ["emission", "phong", "scatter"])
def test_empty_space_skipping_leaves_the_image_bit_identical(phantom_scene, lighting):
    volume, _, camera, transfer_function_for = phantom_scene
    table = transfer_function_for(volume, "ct-bone").to_table(volume.value_range)
    frames = {
        skip: RaymarchRenderer(volume.array, volume.spacing, table, lighting=lighting,
                               empty_space_skipping=skip).render(camera, 96, 96)
        for skip in (True, False)
    }
    np.testing.assert_array_equal(frames[True].rgba, frames[False].rgba)
    assert frames[True].stats["skipped_fraction"] > 0.5
    assert frames[False].stats["skipped_fraction"] == 0.0
    assert frames[True].stats["samples_per_ray"] < 0.5 * frames[False].stats["samples_per_ray"]


def test_early_termination_changes_each_channel_by_at_most_the_remaining_opacity(phantom_scene):
    volume, _, camera, transfer_function_for = phantom_scene
    table = transfer_function_for(volume, "ct-skin").to_table(volume.value_range)
    brightest = float(table.rgba[:, :3].max())
    reference = RaymarchRenderer(volume.array, volume.spacing, table, early_termination=None).render(camera, 96, 96)
    assert reference.stats["early_terminated"] == 0.0
    for threshold in (0.99, 1.0 - 1.0 / 255.0):
        stopped = RaymarchRenderer(volume.array, volume.spacing, table, early_termination=threshold).render(
            camera, 96, 96
        )
        # Bound: what a stopped ray would still collect is (1 - A) * colour <= (1 - threshold) * brightest colour.
        difference = np.abs(stopped.rgba - reference.rgba)
        assert difference[..., :3].max() <= (1.0 - threshold) * brightest + 1e-6
        assert difference[..., 3].max() <= (1.0 - threshold) + 1e-6
        assert stopped.stats["early_terminated"] > 0.2
        assert stopped.stats["samples_per_ray"] < 0.8 * reference.stats["samples_per_ray"]
    # At VTK's threshold 1 - 1/255 the 8-bit image changes by at most one grey level.
    assert np.abs(stopped.to_uint8().astype(int) - reference.to_uint8().astype(int)).max() <= 1


# -- agreement with VTK --------------------------------------------------------------------------------------
@pytest.mark.parametrize("preset", ["ct-bone", "ct-skin"])
def test_emission_matches_vtk_gpu_ray_caster(phantom_scene, preset):
    from app.pipeline.offscreen import render_vtk_volume
    from app.pipeline.props import default_sample_distance

    volume, world_camera, camera, transfer_function_for = phantom_scene
    tf = transfer_function_for(volume, preset, shading=False)
    step = default_sample_distance(volume)
    ours = raymarch(volume.array, tf.to_table(volume.value_range), camera, 160, 160, spacing=volume.spacing,
                    sample_distance=step).to_uint8()
    gpu = render_vtk_volume(volume, world_camera, tf, mapper="gpu", size=(160, 160), sample_distance=step,
                            shading=False)
    # The acceptance point is 28 dB; matching VTK's sampling rule gives 47-49 dB here.
    assert psnr_foreground(ours, gpu) >= 28.0


@pytest.mark.parametrize("preset", ["ct-bone", "ct-skin"])
def test_emission_is_close_to_vtk_cpu_ray_caster(phantom_scene, preset):
    from app.pipeline.offscreen import render_vtk_volume
    from app.pipeline.props import default_sample_distance

    volume, world_camera, camera, transfer_function_for = phantom_scene
    tf = transfer_function_for(volume, preset, shading=False)
    step = default_sample_distance(volume)
    ours = raymarch(volume.array, tf.to_table(volume.value_range), camera, 160, 160, spacing=volume.spacing,
                    sample_distance=step).to_uint8()
    cpu = render_vtk_volume(volume, world_camera, tf, mapper="cpu", size=(160, 160), sample_distance=step,
                            shading=False)
    # vtkFixedPointVolumeRayCastMapper samples and classifies differently (fixed-point rays, its own tables);
    # measured 28.5 dB (bone) and 30.0 dB (skin) on this phantom, mostly at silhouettes. 25 dB catches a wrong
    # camera, axis order or flip (those give 10-15 dB).
    assert psnr_foreground(ours, cpu) >= 25.0


# -- lighting ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ball():
    """A ball of radius 10 mm: the field ``10 - |p|`` (mm), opaque white where it is >= 0."""
    field = sphere_field((33, 33, 33), 10.0)
    rgba = np.zeros((64, 4), dtype=np.float32)
    rgba[:, :3] = 1.0
    rgba[32:, 3] = 1.0  # values >= 0 (table over [-16, 16])
    return field, TransferTable(rgba, -16.0, 16.0)


def test_shading_normals_of_a_ball_point_outwards(ball):
    field, _ = ball
    rng = np.random.default_rng(3)
    directions = rng.standard_normal((50, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points = 16.0 + 8.0 * directions  # on a sphere of radius 8 mm around the centre (16, 16, 16) mm
    normals = shading_normals(field, points)
    # The field decreases outwards, so its gradient points in and the normal -grad/|grad| points out.
    assert np.min(np.sum(normals * directions, axis=1)) > 0.999


def test_shading_normals_of_a_ramp_are_exact():
    ramp = np.broadcast_to(np.arange(6, dtype=np.float32) * 3.0, (5, 4, 6))  # increases along x (i)
    normals = shading_normals(ramp, [[2.5, 1.5, 2.0], [1.2, 2.0, 1.0]], spacing=(2.0, 1.0, 1.0))
    np.testing.assert_allclose(normals, [[-1, 0, 0], [-1, 0, 0]], atol=1e-12)
    flat = shading_normals(np.ones((3, 3, 3)), [[1.0, 1.0, 1.0]])
    np.testing.assert_array_equal(flat, [[0, 0, 0]])


def test_phong_ball_lit_from_the_camera_is_brightest_at_the_centre(ball):
    field, table = ball
    camera = Camera(position=(16, 16, 120), focal_point=(16, 16, 16), view_up=(0, 1, 0), view_angle=20)
    image = RaymarchRenderer(field, (1, 1, 1), table, lighting="phong").render(camera, 64, 64).over()
    brightness = image.mean(axis=2)
    centre = brightness[31:33, 31:33].mean()
    # the ball spans about 10 / (104 tan 10 deg) = 55 % of the half image: 17 pixels; look 15 pixels out
    rim = np.mean([brightness[32, 32 + 15], brightness[32, 32 - 15], brightness[32 + 15, 32], brightness[32 - 15, 32]])
    assert centre == pytest.approx(0.1 + 0.7 + 0.2, abs=0.03)  # n.l = n.h = 1: ambient + diffuse + specular
    assert 0.05 < rim < centre - 0.3
    emission = RaymarchRenderer(field, (1, 1, 1), table).render(camera, 64, 64).over().mean(axis=2)
    assert emission[32, 32 + 15] == pytest.approx(emission[32, 32], abs=1e-6)  # unlit: flat


def test_phong_shading_fades_out_below_the_gradient_threshold(ball):
    field, table = ball
    camera = Camera(position=(16, 16, 120), focal_point=(16, 16, 16), view_up=(0, 1, 0), view_angle=20)
    emission = RaymarchRenderer(field, (1, 1, 1), table).render(camera, 32, 32).rgba
    # |grad f| = 1 per mm for this field: a threshold of 1e6 leaves a shading weight of 1e-6.
    faded = RaymarchRenderer(field, (1, 1, 1), table, lighting="phong", gradient_threshold=1e6).render(camera, 32, 32)
    np.testing.assert_allclose(faded.rgba, emission, atol=2e-6)
    # At threshold 2 (twice |grad f|) the colour is halfway between unshaded and fully shaded.
    full = RaymarchRenderer(field, (1, 1, 1), table, lighting="phong").render(camera, 32, 32).rgba
    half = RaymarchRenderer(field, (1, 1, 1), table, lighting="phong", gradient_threshold=2.0).render(camera, 32, 32)
    np.testing.assert_allclose(half.rgba[15:17, 15:17], 0.5 * (full + emission)[15:17, 15:17], atol=0.02)


def test_scatter_sample_in_the_shadow_of_a_slab_is_darker():
    # A faint medium fills the box; an opaque wall occupies x >= 20 mm for y < 16 mm. Light comes from +x, the
    # camera looks down -z at the strip x < 12 mm where only the medium is: the half with y < 16 mm lies in the
    # wall's shadow.
    volume = np.full((9, 33, 33), 50.0, dtype=np.float32)
    volume[:, :16, 20:] = 150.0
    rgba = np.array([[1, 1, 1, 0.02], [1, 1, 1, 0.02], [1, 1, 1, 1.0], [1, 1, 1, 1.0]], dtype=np.float32)
    table = TransferTable(rgba, 0.0, 200.0)  # value 50: 0.02 per mm, value 150: opaque
    renderer = RaymarchRenderer(volume, (1, 1, 1), table, lighting="scatter", light_direction=(1, 0, 0),
                                light_samples=8)
    image = renderer.render(top_down_camera((16, 16), 16.0), 32, 32).rgba
    # pixel centres: x = col + 0.5, y = 31.5 - row (mm); compare x in [2, 10], y in [4, 12] vs y in [20, 28]
    shadowed = image[20:28, 2:10, 0]
    lit = image[4:12, 2:10, 0]
    assert shadowed.max() < 0.05 * lit.min()
    assert lit.min() > 0.02
    # Without the wall, the two halves would be equally bright: the only difference is the light reaching them.
    uniform = RaymarchRenderer(np.full_like(volume, 50.0), (1, 1, 1), table, lighting="scatter",
                               light_direction=(1, 0, 0)).render(top_down_camera((16, 16), 16.0), 32, 32).rgba
    np.testing.assert_allclose(uniform[20:28, 2:10], uniform[4:12, 2:10], rtol=1e-5)
    # The scattered light scales with the albedo (the opacity does not).
    half = RaymarchRenderer(volume, (1, 1, 1), table, lighting="scatter", light_direction=(1, 0, 0),
                            scatter_albedo=0.5).render(top_down_camera((16, 16), 16.0), 32, 32).rgba
    np.testing.assert_allclose(half[..., :3], 0.5 * image[..., :3], rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(half[..., 3], image[..., 3])


def test_the_renderer_keeps_its_own_copy_of_the_volume(slab):
    volume, spacing = slab
    mine = volume.copy()
    ramp = TransferTable(np.array([[*COLOUR, 0.0], [*COLOUR, 0.4]], dtype=np.float32), 0.0, 200.0)
    renderer = RaymarchRenderer(mine, spacing, ramp)
    before = renderer.render(top_down_camera((4, 4), 3.0), 8, 8).rgba
    assert before[..., 3].min() > 0.9
    mine[:] = 0.0  # the caller changes its array afterwards (value 0 would be transparent)
    np.testing.assert_array_equal(renderer.render(top_down_camera((4, 4), 3.0), 8, 8).rgba, before)


# -- VTK filter ------------------------------------------------------------------------------------------------
def test_filter_renders_the_same_frame_with_vtk_row_order(phantom_scene):
    from vtkmodules.util import numpy_support

    volume, _, camera, transfer_function_for = phantom_scene
    table = transfer_function_for(volume, "ct-bone").to_table(volume.value_range)
    origin = (-30.0, 12.0, 5.0)
    image = image_from_array(volume.array, volume.spacing, origin)
    filt = RaymarchFilter()
    filt.SetInputDataObject(image)
    filt.SetTransferTable(table)
    shift = np.eye(4)
    shift[:3, 3] = origin
    filt.SetCamera(camera.transformed(shift))  # the same view in the image's (shifted) coordinates
    filt.SetImageSize(48, 40)
    output = run_algorithm(filt)
    assert output.GetDimensions() == (48, 40, 1)
    scalars = output.GetPointData().GetScalars()
    assert scalars.GetNumberOfComponents() == 4 and scalars.GetDataTypeAsString() == "unsigned char"
    pixels = numpy_support.vtk_to_numpy(scalars).reshape(40, 48, 4)[::-1]  # VTK rows start at the bottom
    expected = RaymarchRenderer(volume.array, volume.spacing, table).render(camera, 48, 40).rgba
    np.testing.assert_array_equal(pixels, np.clip(np.rint(expected * 255), 0, 255).astype(np.uint8))
    assert filt.last_stats["rays"] == 48 * 40


def test_filter_reports_a_missing_camera_and_a_rotated_image():
    table = constant_table(0.1)
    image = image_from_array(np.zeros((4, 4, 4), dtype=np.float32))
    filt = RaymarchFilter()
    filt.SetInputDataObject(image)
    filt.SetTransferTable(table)
    with pytest.raises(VTKError, match="needs a camera"):
        run_algorithm(filt)
    filt.SetCamera(top_down_camera((1.5, 1.5), 2.0))
    image.SetDirectionMatrix(0, 1, 0, 1, 0, 0, 0, 0, 1)
    image.Modified()
    with pytest.raises(VTKError, match="identity direction"):
        run_algorithm(filt)


def test_filter_setters_modify_only_on_change():
    filt = RaymarchFilter()
    filt.SetLighting("phong")
    filt.SetSampleDistance(0.5)
    filt.SetImageSize(10, 20)
    stamp = filt.GetMTime()
    filt.SetLighting("phong")
    filt.SetSampleDistance(0.5)
    filt.SetImageSize(10, 20)
    assert filt.GetMTime() == stamp
    filt.SetSampleDistance(None)
    assert filt.GetMTime() > stamp
    assert (filt.GetLighting(), filt.GetSampleDistance(), filt.GetImageSize()) == ("phong", None, (10, 20))


def test_progress_can_cancel_a_frame(phantom_scene):
    volume, _, camera, transfer_function_for = phantom_scene
    table = transfer_function_for(volume, "ct-bone").to_table(volume.value_range)
    renderer = RaymarchRenderer(volume.array, volume.spacing, table)
    seen = []

    def cancel_midway(fraction):
        seen.append(fraction)
        if fraction > 0.3:
            raise OperationCancelled

    with pytest.raises(OperationCancelled):
        renderer.render(camera, 64, 128, progress=cancel_midway)
    assert 0 < seen[-1] < 1

    filt = RaymarchFilter()
    filt.SetInputDataObject(volume.to_vtk(local=True))
    filt.SetTransferTable(table)
    filt.SetCamera(camera)
    filt.SetImageSize(64, 128)
    with pytest.raises(OperationCancelled):
        run_algorithm(filt, progress=cancel_midway)


# -- errors -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "volume, spacing, options, message",
    [
        (np.zeros((4, 4)), (1, 1, 1), {}, "3D volume"),
        (np.zeros((1, 4, 4)), (1, 1, 1), {}, "at least 2 voxels"),
        (np.zeros((3, 3, 3), complex), (1, 1, 1), {}, "real-valued"),
        (np.full((3, 3, 3), np.nan), (1, 1, 1), {}, "NaN"),
        (np.zeros((3, 3, 3)), (1, 0, 1), {}, "spacing"),
        (np.zeros((3, 3, 3)), (1, 1), {}, "spacing"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"sample_distance": 0.0}, "sample_distance"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"sample_distance": math.inf}, "sample_distance"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"lighting": "toon"}, "lighting"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"light_samples": 0}, "light_samples"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"light_samples": 2.5}, "light_samples"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"light_direction": (0, 0, 0)}, "light_direction"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"light_direction": (1, 0)}, "light_direction"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"ambient": -0.1}, "ambient"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"diffuse": math.nan}, "diffuse"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"specular": -1}, "specular"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"specular_power": 0}, "specular_power"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"gradient_threshold": -1}, "gradient_threshold"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"early_termination": 0.0}, "early_termination"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"early_termination": 1.5}, "early_termination"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"brick_size": 0}, "brick_size"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"scatter_albedo": 1.2}, "scatter_albedo"),
        (np.zeros((3, 3, 3)), (1, 1, 1), {"phase": 1.0}, "phase"),
    ],
)
def test_invalid_renderer_arguments(volume, spacing, options, message):
    with pytest.raises(ValueError, match=message):
        RaymarchRenderer(volume, spacing, constant_table(0.1), **options)


def test_invalid_frame_and_helper_arguments():
    renderer = RaymarchRenderer(np.zeros((3, 3, 3)), (1, 1, 1), constant_table(0.1))
    camera = top_down_camera((1, 1), 2.0)
    with pytest.raises(ValueError, match="image size"):
        renderer.render(camera, 0, 10)
    with pytest.raises(ValueError, match="image size"):
        renderer.render(camera, 10, 2.5)
    with pytest.raises(TypeError, match="Camera"):
        renderer.render("front", 10, 10)
    with pytest.raises(TypeError, match="TransferTable"):
        RaymarchRenderer(np.zeros((3, 3, 3)), (1, 1, 1), np.zeros((4, 4)))
    with pytest.raises(ValueError, match="samples"):
        step_for_samples((3, 3, 3), (1, 1, 1), 0)
    with pytest.raises(ValueError, match="shape"):
        step_for_samples((3, 1, 3), (1, 1, 1), 10)
    with pytest.raises(ValueError, match=r"points must have shape \(n, 3\)"):
        shading_normals(np.zeros((3, 3, 3)), [1.0, 2.0, 3.0])
    filt = RaymarchFilter()
    with pytest.raises(ValueError, match="lighting"):
        filt.SetLighting("toon")
    with pytest.raises(ValueError, match="sample_distance"):
        filt.SetSampleDistance(-1)
    with pytest.raises(ValueError, match="image size"):
        filt.SetImageSize(0, 5)
