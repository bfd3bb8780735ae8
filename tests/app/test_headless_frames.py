"""Headless renders of our software renderers without an OpenGL context (issue 20, memory): the picture is the
renderer's frame, pixel for pixel what the OpenGL path read back; VTK's modes keep their off-screen window; the
stand-in renderer's camera reads back what a ``vtkCamera`` does and it refuses VTK props; a raymarch render of a
NIfTI file loads neither VTK's rendering modules nor pydicom; the frame's compositing over the background is the
plain formula."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import app.pipeline.headless as headless
from app.modes import get_mode
from app.pipeline.frames import rgba_to_rgb
from app.pipeline.headless import RenderSettings, picture_is_frame, render_item
from app.scene import VolumeItem

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def item():
    from app.datasets import ct_head_phantom

    return VolumeItem("ct", volume=ct_head_phantom(shape=(40, 64, 64), spacing=(3.75, 3.75, 5.4)))


def test_software_modes_take_their_frame_and_vtk_modes_keep_opengl():
    for name, options in (("raymarch", {}), ("shear-warp", {}), ("slicing", {}), ("slicing-axis", {})):
        mode = get_mode(name)
        assert picture_is_frame(mode, mode.resolve_options(options)), name
    slicing = get_mode("slicing")
    assert not picture_is_frame(slicing, slicing.resolve_options({"compositing": "gl"}))  # blended by OpenGL
    for name in ("vtk-gpu", "vtk-cpu", "marching-cubes", "raymarch-vs-vtk-gpu"):
        mode = get_mode(name)
        assert not picture_is_frame(mode, mode.resolve_options({})), name


@pytest.mark.parametrize("mode, settings", [
    ("raymarch", dict(background=(0.2, 0.3, 0.9), azimuth=30.0)),
    ("raymarch", dict(options={"jitter": True, "passes": 3})),
    ("shear-warp", dict(parallel=True, background=(1.0, 1.0, 1.0), frames=2)),
    ("slicing", dict(elevation=20.0, frames=1)),
    ("slicing-axis", dict(background=(0.5, 0.5, 0.5))),
])
def test_frame_picture_is_what_the_opengl_path_reads_back(item, monkeypatch, mode, settings):
    wanted = RenderSettings(mode=get_mode(mode), size=(72, 56), **settings)
    without_gl = render_item(item, wanted)
    assert without_gl.image.shape == (56, 72, 3) and without_gl.image.std() > 0
    np.testing.assert_array_equal(without_gl.image, without_gl.frame)
    with monkeypatch.context() as patch:
        patch.setattr(headless, "picture_is_frame", lambda mode, options: False)  # the off-screen OpenGL window
        with_gl = render_item(item, wanted)
    np.testing.assert_array_equal(without_gl.image, with_gl.image)
    if settings.get("frames"):
        assert without_gl.info["frames"] == with_gl.info["frames"] == settings["frames"]


def test_compositing_over_the_background_is_the_plain_formula():
    colour, alpha = np.meshgrid(np.arange(256), np.arange(256))
    rgba = np.stack([colour, np.minimum(colour, alpha), colour // 2, alpha], axis=-1).astype(np.uint8)
    for background in ((0.0, 0.0, 0.0), (0.2, 0.3, 0.9), (1.0, 1.0, 1.0), (0.123, 0.777, 0.31)):
        back = np.asarray(background, dtype=np.float32) * np.float32(255.0)
        transparency = np.float32(1.0) - rgba[..., 3:4].astype(np.float32) / np.float32(255.0)
        expected = np.clip(np.rint(rgba[..., :3].astype(np.float32) + transparency * back), 0, 255).astype(np.uint8)
        np.testing.assert_array_equal(rgba_to_rgb(rgba[::-1], background), expected[::-1])


def test_a_raymarch_render_of_a_nifti_loads_no_vtk_rendering_and_no_pydicom(tmp_path, item):
    from app.io import save_volume

    path = save_volume(item.volume, tmp_path / "ct.nii")
    code = (
        "import json, sys\n"
        "from app.cli import main\n"
        f"code = main(['render', {str(path)!r}, '--mode', 'raymarch', '--size', '48', '40', '-o', "
        f"{str(tmp_path / 'out.png')!r}, '--json'])\n"
        "print(json.dumps({'code': code, 'modules': [m for m in sys.modules if m == 'pydicom' or "
        "m.startswith('vtkmodules.vtkRendering')]}))\n"
        "import pydicom, nibabel\n"  # pydicom still imports normally afterwards
        "print(json.dumps({'pydicom': bool(pydicom.__version__), 'nibabel_dicom': nibabel.nifti1.have_dicom}))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    lines = result.stdout.strip().splitlines()
    loaded, after = json.loads(lines[-2]), json.loads(lines[-1])
    assert loaded == {"code": 0, "modules": []}
    assert after == {"pydicom": True, "nibabel_dicom": False}  # DICOM header extensions stay raw bytes
    assert (tmp_path / "out.png").stat().st_size > 0


def test_with_other_threads_running_nibabel_is_imported_as_it_is(tmp_path, item):
    """Hiding pydicom is only safe while no other thread could import it meanwhile (the window, Dask workers)."""
    from app.io import save_volume

    path = save_volume(item.volume, tmp_path / "ct.nii")
    code = (
        "import json, sys, threading\n"
        "stop = threading.Event()\n"
        "threading.Thread(target=stop.wait, daemon=True).start()\n"
        "from app.io import load_volume\n"
        f"load_volume({str(path)!r})\n"
        "import nibabel\n"
        "print(json.dumps({'pydicom': 'pydicom' in sys.modules, 'nibabel_dicom': nibabel.nifti1.have_dicom}))\n"
        "stop.set()\n"
    )
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1]) == {"pydicom": True, "nibabel_dicom": True}


def test_a_single_pass_keeps_no_running_sum(item):
    from app.modes.renderers import RendererContent
    from app.pipeline.jobs import ImmediateRunner
    from app.pipeline.offscreen import FrameScene
    from app.pipeline.view import ViewPipeline

    for options, kept in (({"jitter": False}, False), ({"jitter": True, "passes": 2}, True)):
        scene = FrameScene((40, 32))
        pipeline = ViewPipeline(scene.renderer, ImmediateRunner(), lambda: (40, 32))
        pipeline.set_camera(headless.default_camera(item, view="anterior", aspect=40 / 32))
        pipeline.set_inputs(headless.view_inputs(item, uses_iso=False))
        pipeline.set_mode(get_mode("raymarch"), options)
        content = pipeline.content
        assert isinstance(content, RendererContent) and pipeline.last_frame.stats["passes"] == (2 if kept else 1)
        assert (content._sum is not None) == kept and pipeline.last_frame.image.shape == (32, 40, 3)
        pipeline.shutdown()
        scene.close()


def test_the_frame_camera_reads_back_what_a_vtk_camera_does():
    from vtkmodules.vtkRenderingCore import vtkCamera

    from algorithms.common.camera import Camera
    from app.pipeline.offscreen import FrameCamera

    rng = np.random.default_rng(20)
    ours, theirs = FrameCamera(), vtkCamera()
    assert Camera.from_vtk(ours) == Camera.from_vtk(theirs)  # the defaults
    for index in range(2000):
        position, focal_point, view_up = (tuple(rng.normal(size=3) * 10.0 ** rng.uniform(-3, 3)) for _ in range(3))
        view_up = (0.0, 0.0, 0.0) if index == 7 else view_up
        view_angle = float(rng.choice([1e-9, 0.5, 30.0, 179.0, 200.0]))
        scale = float(rng.uniform(0.1, 500.0))
        for camera in (ours, theirs):
            camera.SetPosition(*position)
            camera.SetFocalPoint(*focal_point)
            camera.SetViewUp(*view_up)
            camera.SetViewAngle(view_angle)
            camera.SetParallelProjection(index % 2)
            camera.SetParallelScale(scale)
        for getter in ("GetPosition", "GetFocalPoint", "GetViewUp", "GetViewAngle", "GetParallelProjection",
                       "GetParallelScale"):
            assert getattr(ours, getter)() == getattr(theirs, getter)(), (index, getter)


def test_the_frame_renderer_refuses_vtk_props_and_keeps_the_last_frame():
    from vtkmodules.vtkRenderingCore import vtkActor

    from app.pipeline.offscreen import FrameScene

    scene = FrameScene((4, 3))
    for add in (scene.renderer.AddActor, scene.renderer.AddViewProp, scene.renderer.AddVolume):
        with pytest.raises(TypeError, match="draws no VTK props"):
            add(vtkActor())
    with pytest.raises(RuntimeError, match="no frame"):
        scene.capture()
    scene.renderer.show_frame(np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(RuntimeError, match="4 x 4 pixels, the scene 4 x 3"):
        scene.capture()
    frame = np.arange(36, dtype=np.uint8).reshape(3, 4, 3)
    scene.renderer.show_frame(frame)
    captured = scene.capture()
    np.testing.assert_array_equal(captured, frame)
    assert captured is not frame
    scene.renderer.TexturedBackgroundOff()  # the view pipeline clears the background when the content changes
    with pytest.raises(RuntimeError, match="no frame"):
        scene.capture()
