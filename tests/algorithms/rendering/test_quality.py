"""Issue 17's picture-quality checks of our software renderers: ring energy (banding) with and without jitter on a
smooth phantom, stable jitter, shading in texture slicing, VTK's light model in the ray marcher, shear-warp on an
anisotropic CT and in perspective, each against VTK's GPU ray caster on the same frame."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.camera import Camera
from algorithms.common.render_result import RenderResult
from algorithms.common.sampling import jitter_offset, jitter_pattern
from algorithms.common.transfer import TransferTable
from algorithms.compare.image_metrics import psnr_foreground
from algorithms.datasets.volumes import sphere_field
from algorithms.rendering.banding import radial_profile, ring_energy
from algorithms.rendering.raymarch import RaymarchRenderer
from algorithms.rendering.shear_warp import ShearWarpRenderer
from algorithms.rendering.texture_slicing import SlicingRenderer

N = 96
SIZE = 192
#: A semi-transparent shell 4 mm thick under the surface of a ball of radius 40 mm, coloured from blue outside
#: to yellow inside: every ray crosses the shell at a slant except at the centre, so sampling at fixed depths
#: draws rings.
SHELL = TransferTable.from_points([(0, 0.2, 0.3, 0.9), (4, 1.0, 0.9, 0.3)],
                                  [(0, 0.0), (0.5, 0.25), (4, 0.25), (5, 0.0)], (-50, 50))


@pytest.fixture(scope="module")
def ball():
    return sphere_field((N, N, N), 40.0)


def _camera() -> Camera:
    # Looking straight down z: the renderers' sample planes (box entry face, view-aligned slices, voxel slices)
    # are all perpendicular to the view, so every renderer's rings are centred on the image centre.
    c = (N - 1) / 2
    return Camera(position=(c, c, c + 250), focal_point=(c, c, c), view_up=(0, 1, 0), parallel_projection=True,
                  parallel_scale=48)


def _rings(result) -> float:
    return ring_energy(result.over(), (SIZE / 2, SIZE / 2), 70)


RENDERERS = {
    "raymarch": lambda volume, jitter: RaymarchRenderer(volume, (1, 1, 1), SHELL, sample_distance=1.0, jitter=jitter),
    "slicing": lambda volume, jitter: SlicingRenderer(volume, (1, 1, 1), SHELL, jitter=jitter),
    "shear-warp": lambda volume, jitter: ShearWarpRenderer(volume, (1, 1, 1), SHELL, jitter=jitter),
}


@pytest.fixture(scope="module")
def ring_floor(ball):
    """The ring energy of a picture without rings: ray marching at a tenth of a voxel (0.00245). What is left is
    the metric's reading of the shell's own radial profile, which no renderer can (or should) remove."""
    return _rings(RaymarchRenderer(ball, (1, 1, 1), SHELL, sample_distance=0.1).render(_camera(), SIZE, SIZE))


def test_ring_energy_sees_rings_and_ignores_noise():
    rows, cols = np.mgrid[0:SIZE, 0:SIZE]
    radius = np.hypot(cols + 0.5 - SIZE / 2, rows + 0.5 - SIZE / 2)
    rings = 0.5 + 0.02 * np.sin(radius * 2 * np.pi / 5.0)
    noise = 0.5 + 0.02 * np.random.default_rng(0).standard_normal((SIZE, SIZE))
    assert ring_energy(rings, (SIZE / 2, SIZE / 2), 70) > 0.01
    assert ring_energy(noise, (SIZE / 2, SIZE / 2), 70) < 0.002
    assert radial_profile(np.full((16, 16), 0.25), (8, 8), 6) == pytest.approx(np.full(6, 0.25))


@pytest.mark.parametrize("name", sorted(RENDERERS))
def test_jitter_removes_most_of_the_ring_energy(ball, ring_floor, name):
    plain = _rings(RENDERERS[name](ball, False).render(_camera(), SIZE, SIZE))
    jittered = _rings(RENDERERS[name](ball, True).render(_camera(), SIZE, SIZE))
    # Ring energy above the ring-free floor (0.00245). Unjittered: 0.0063 (raymarch), 0.0061 (slicing), 0.0047
    # (shear-warp); jittered, one pass: 0.0025, 0.0021, 0.0025 - at the floor.
    assert plain - ring_floor > 0.0015
    assert jittered - ring_floor < 0.2 * (plain - ring_floor)


def test_jittered_shear_warp_converges_to_the_ring_free_picture(ball):
    # Shear-warp classifies voxels before resampling them (source 004): its unjittered frame keeps the terraces of
    # the shell's classified voxels. The jittered kernel samples the scalar field between slice crossings and
    # classifies it there, so the mean of its passes converges to the integral a fine ray march computes, as ray
    # marching's own jittered passes do (measured at 96 x 96: 53.5 dB for both, 41.6 dB unjittered).
    def mean_of_passes(renderer, passes=16):
        rgba = [renderer.render(_camera(), 96, 96, pass_index=p).rgba for p in range(passes)]
        return RenderResult(np.mean(rgba, axis=0)).to_uint8()

    fine = RaymarchRenderer(ball, (1, 1, 1), SHELL, sample_distance=0.1).render(_camera(), 96, 96).to_uint8()
    plain = ShearWarpRenderer(ball, (1, 1, 1), SHELL).render(_camera(), 96, 96).to_uint8()
    jittered = mean_of_passes(ShearWarpRenderer(ball, (1, 1, 1), SHELL, jitter=True))
    marched = mean_of_passes(RaymarchRenderer(ball, (1, 1, 1), SHELL, sample_distance=1.0, jitter=True))
    assert psnr_foreground(jittered, fine) > 50.0
    assert psnr_foreground(jittered, fine) > psnr_foreground(plain, fine) + 8.0
    assert psnr_foreground(jittered, marched) > 50.0


@pytest.mark.parametrize("name", sorted(RENDERERS) + ["shear-warp"])
def test_jitter_is_stable_and_passes_average_towards_the_unjittered_frame(ball, name):
    make = RENDERERS.get(name, lambda volume, jitter: ShearWarpRenderer(volume, (1, 1, 1), SHELL, jitter=jitter))
    renderer = make(ball, True)
    first = renderer.render(_camera(), 64, 64).rgba
    np.testing.assert_array_equal(renderer.render(_camera(), 64, 64).rgba, first)  # no flicker
    second = renderer.render(_camera(), 64, 64, pass_index=1).rgba
    assert not np.array_equal(second, first)
    mean = np.mean([renderer.render(_camera(), 64, 64, pass_index=p).rgba for p in range(8)], axis=0)
    plain = make(ball, False).render(_camera(), 64, 64).rgba
    assert np.abs(mean - plain).mean() < np.abs(first - plain).mean()


def test_jitter_pattern_is_a_uniform_spread_in_every_small_block():
    pattern = jitter_pattern(64, 64)
    assert pattern.min() >= 0 and pattern.max() < 1
    assert abs(pattern.mean() - 0.5) < 0.01
    # Every 4 x 4 block holds offsets from every quarter of [0, 1).
    for row in range(0, 64, 4):
        for col in range(0, 64, 4):
            quarters = np.floor(pattern[row:row + 4, col:col + 4] * 4)
            assert set(np.unique(quarters)) == {0, 1, 2, 3}
    assert not np.array_equal(jitter_pattern(8, 8, 1), jitter_pattern(8, 8, 0))
    # The pattern is the renderers' own per-pixel offset (the kernels call jitter_offset).
    for pass_index in (0, 3):
        offsets = jitter_pattern(64, 64, pass_index)
        for row, col in ((0, 0), (5, 17), (63, 40), (31, 2)):
            assert jitter_offset(col, row, pass_index) == pytest.approx(offsets[row, col], abs=1e-12)


# -- against VTK -------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def phantom_view(ct_phantom):
    from app.pipeline import camera_in_frame, default_camera
    from app.transfer import transfer_function_for

    world = default_camera(ct_phantom, azimuth=30, elevation=15)
    return ct_phantom, world, camera_in_frame(world, ct_phantom.local_to_world), transfer_function_for


def _vtk_gpu(volume, function, world_camera, size, *, shading):
    from app.bench.common import vtk_mapper_scene

    scene = vtk_mapper_scene(volume, function, "gpu", size, sample_distance=0.5 * min(volume.spacing),
                             shading=shading, camera=world_camera)
    try:
        scene.render()
        return scene.capture()
    finally:
        scene.close()


def _material(function) -> dict:
    shading = function.shading
    return dict(ambient=shading.ambient, diffuse=shading.diffuse, specular=shading.specular,
                specular_power=shading.specular_power)


def test_shaded_raymarch_uses_vtk_light_model(phantom_view):
    volume, world, camera, transfer_function_for = phantom_view
    function = transfer_function_for(volume, "ct-bone", shading=True)
    reference = _vtk_gpu(volume, function, world, 256, shading=True)
    ours = RaymarchRenderer(volume.array, volume.spacing, function.to_table(volume.value_range),
                            sample_distance=0.5 * min(volume.spacing), lighting="phong", **_material(function))
    assert psnr_foreground(ours.render(camera, 256, 256).to_uint8(), reference) >= 30.0  # measured 48 dB


def test_shading_changes_texture_slicing_and_matches_shaded_vtk(phantom_view):
    volume, world, camera, transfer_function_for = phantom_view
    function = transfer_function_for(volume, "ct-bone", shading=True)
    table = function.to_table(volume.value_range)
    reference = _vtk_gpu(volume, function, world, 256, shading=True)
    flat = SlicingRenderer(volume.array, volume.spacing, table).render(camera, 256, 256).to_uint8()
    shaded = SlicingRenderer(volume.array, volume.spacing, table, shading=True, **_material(function))
    shaded = shaded.render(camera, 256, 256).to_uint8()
    assert np.sqrt(np.mean((shaded.astype(float) - flat) ** 2)) > 5.0
    assert psnr_foreground(shaded, reference) >= 26.0  # measured 41 dB
    assert psnr_foreground(flat, reference) < 20.0


_THIN_BONE = pytest.mark.xfail(strict=True, reason=(
    "issue 34: on the FORBILD head's thin bone shear-warp is more opaque and banded than VTK's ray caster: 23.7 dB "
    "parallel, 22.8 dB perspective, as on a real CT (24.3 dB); the floors were met on the egg phantom only"))


@pytest.mark.parametrize("phantom", ["egg", pytest.param("forbild", marks=_THIN_BONE)])
@pytest.mark.parametrize("parallel, floor", [(True, 26.0), (False, 24.0)])
def test_shear_warp_on_an_anisotropic_ct_parallel_and_perspective(parallel, floor, phantom):
    from app.datasets import ct_head_phantom, egg_head_phantom
    from app.pipeline import camera_in_frame, default_camera
    from app.transfer import transfer_function_for

    make = egg_head_phantom if phantom == "egg" else ct_head_phantom
    volume = make(shape=(96, 168, 168), spacing=(0.96, 0.96, 1.5))  # a CT's anisotropic voxels
    function = transfer_function_for(volume, "ct-bone", shading=False)
    world = default_camera(volume, elevation=20.0, parallel=parallel)
    reference = _vtk_gpu(volume, function, world, 256, shading=False)
    renderer = ShearWarpRenderer(volume.array, volume.spacing, function.to_table(volume.value_range))
    assert renderer.spacing == pytest.approx((0.96, 0.96, 0.96), rel=0.03)  # resampled by default
    frame = renderer.render(camera_in_frame(world, volume.local_to_world), 256, 256)
    assert frame.stats["perspective"] == (0.0 if parallel else 1.0)
    assert psnr_foreground(frame.to_uint8(), reference) >= floor
    own_grid = ShearWarpRenderer(volume.array, volume.spacing, function.to_table(volume.value_range),
                                 resample_spacing=None).render(camera_in_frame(world, volume.local_to_world), 256, 256)
    assert psnr_foreground(frame.to_uint8(), reference) > psnr_foreground(own_grid.to_uint8(), reference)


def test_renderers_sample_a_read_only_volume_without_copying_it():
    volume = np.zeros((8, 8, 8), dtype=np.int16)
    volume.setflags(write=False)
    table = TransferTable.from_points([(0, 1, 1, 1)], [(0, 0.0), (10, 1.0)], (0, 10))
    assert np.shares_memory(RaymarchRenderer(volume, (1, 1, 1), table).volume, volume)
    assert np.shares_memory(SlicingRenderer(volume, (1, 1, 1), table).volume, volume)
    assert np.shares_memory(ShearWarpRenderer(volume, (1, 1, 1), table)._values, volume)
    writable = np.zeros((8, 8, 8), dtype=np.int16)
    copy = RaymarchRenderer(writable, (1, 1, 1), table).volume
    assert not np.shares_memory(copy, writable) and copy.dtype == np.int16


def test_frames_over_background_accumulate_like_the_mean_of_passes():
    rgba = np.random.default_rng(1).random((4, 4, 4)).astype(np.float32) * 0.5
    mean = RenderResult(np.mean([rgba, rgba * 0.5], axis=0)).over()
    np.testing.assert_allclose(mean, np.mean([RenderResult(rgba).over(), RenderResult(rgba * 0.5).over()], 0),
                               atol=1e-6)
