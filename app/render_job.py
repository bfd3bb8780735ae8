"""One off-screen render of any mode, with frame timing: the logic behind ``voxelscope render``.

Surface, VTK volume and software-image modes all go through :func:`render_volume`, so their JSON reports carry
the same fields: set-up seconds (mesh extraction, mapper set-up, classification/encoding, first frame) apart
from the per-frame seconds of a turning camera.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from algorithms._progress import ProgressCallback
from algorithms.camera import Camera

from .io.atomic import atomic_output
from .compare import DISTANCE_ARRAY, image_difference, surface_distance
from .meshing import default_iso
from .modes import get_mode
from .rendering import (
    DEFAULT_SIZE,
    FrameTimes,
    OffscreenScene,
    default_camera,
    default_sample_distance,
    distance_actor,
    surface_actor,
    turning_cameras,
    volume_prop,
)
from .transfer import transfer_function_for
from .volume import Volume


@dataclass
class RenderSettings:
    """What to render and how; the defaults are the command line's."""

    mode: str
    preset: str | None = None
    size: tuple[int, int] = DEFAULT_SIZE
    view: str = "anterior"
    azimuth: float = 0.0
    elevation: float = 0.0
    parallel: bool = False
    shading: bool | None = None
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frames: int = 0
    iso: float | None = None
    sample_distance: float | None = None
    options: dict[str, Any] = field(default_factory=dict)


@dataclass
class RenderReport:
    image: np.ndarray  # (h, w, 3) uint8, row 0 at the top
    info: dict[str, Any]


def surface_color(volume: Volume, iso: float) -> tuple[float, float, float]:
    """A material colour for an isosurface: skin, soft tissue or bone for CT by the isovalue (HU), grey otherwise."""
    if volume.units == "HU":
        if iso < -200:
            return (0.93, 0.74, 0.62)  # skin
        if iso < 150:
            return (0.85, 0.45, 0.40)  # soft tissue
        return (0.91, 0.86, 0.72)  # bone
    return (0.85, 0.85, 0.85)


class _SceneRenderer:
    """Frames of a VTK scene (surface or VTK volume mapper)."""

    def __init__(self, scene: OffscreenScene) -> None:
        self.scene = scene

    def frame(self, camera: Camera) -> np.ndarray | None:
        self.scene.set_camera(camera)
        self.scene.render()
        return None

    def capture(self) -> np.ndarray:
        return self.scene.capture()

    def close(self) -> None:
        self.scene.close()


class _SliceStackRenderer(_SceneRenderer):
    """Texture slicing drawn by OpenGL: the slices are regenerated for each camera and blended by VTK."""

    def __init__(self, slicer, volume: Volume, size, background) -> None:
        from algorithms.texture_slicing import SliceStackProp

        super().__init__(OffscreenScene(size, background))
        self.stack = SliceStackProp(slicer, user_matrix=volume.local_to_world)
        self.stack.attach(self.scene.renderer)
        self.to_local = np.linalg.inv(volume.local_to_world)
        self.size = size

    def frame(self, camera: Camera):
        self.stack.update(camera.transformed(self.to_local), *self.size)
        return super().frame(camera)


class _ImageRenderer:
    """Frames of one of our software renderers; cameras are converted to the volume frame."""

    def __init__(self, renderer, volume: Volume, size, background) -> None:
        self.renderer = renderer
        self.to_local = np.linalg.inv(volume.local_to_world)
        self.size = size
        self.background = background
        self.last = None

    def frame(self, camera: Camera):
        self.last = self.renderer.render(camera.transformed(self.to_local), *self.size)
        return self.last

    def capture(self) -> np.ndarray:
        return self.last.to_uint8(self.background)

    def close(self) -> None:
        pass


class _DifferenceRenderer(_ImageRenderer):
    """Our renderer against a VTK mapper at the same camera: the frame is the heat map of their difference."""

    def __init__(self, renderer, reference: OffscreenScene, volume: Volume, size, background) -> None:
        super().__init__(renderer, volume, size, background)
        self.reference = reference
        self.difference = None

    def frame(self, camera: Camera):
        result = super().frame(camera)
        self.reference.set_camera(camera)
        self.reference.render()
        self.difference = image_difference(result.to_uint8(self.background), self.reference.capture(),
                                           background=self.background)
        return result

    def capture(self) -> np.ndarray:
        return self.difference.heatmap

    def close(self) -> None:
        self.reference.close()


def render_volume(volume: Volume, settings: RenderSettings, *, progress: ProgressCallback = None) -> RenderReport:
    """Render ``volume`` off-screen as ``settings`` say; time set-up and, with ``frames``, a turning camera."""
    mode = get_mode(settings.mode)
    width, height = (int(v) for v in settings.size)
    if width < 8 or height < 8 or width > 8192 or height > 8192:
        raise ValueError(f"image size must be between 8 and 8192 pixels per side, got {width} x {height}")
    if settings.frames < 0:
        raise ValueError(f"frames must be 0 or more, got {settings.frames}")
    if getattr(mode, "parallel_only", False) and not settings.parallel:
        raise ValueError(f"mode {mode.name!r} renders with parallel projection only; add --parallel")
    if settings.options.get("compositing") == "gl" and not mode.name.startswith("slicing"):
        raise ValueError("--compositing applies to the slicing modes only")
    transfer_function = transfer_function_for(volume, settings.preset, shading=settings.shading)
    camera = default_camera(volume, view=settings.view, azimuth=settings.azimuth, elevation=settings.elevation,
                            parallel=settings.parallel, aspect=width / height)
    step = settings.sample_distance if settings.sample_distance is not None else default_sample_distance(volume)
    info: dict[str, Any] = {
        "mode": mode.name,
        "kind": mode.kind,
        "preset": transfer_function.name,
        "size": [width, height],
        "camera": {
            "position": [round(v, 4) for v in camera.position],
            "focal_point": [round(v, 4) for v in camera.focal_point],
            "view_up": [round(v, 6) for v in camera.view_up],
            "parallel": camera.parallel_projection,
            "coordinates": "LPS mm",
        },
        "shading": transfer_function.shading.enabled,
    }

    start = time.perf_counter()
    if mode.kind == "surface":
        iso = settings.iso if settings.iso is not None else default_iso(volume)
        result = mode.extract(volume, iso, progress=progress)
        scene = OffscreenScene((width, height), settings.background)
        scene.add(surface_actor(result.polydata, volume, color=surface_color(volume, iso),
                                flat=mode.flat_shading))
        runner: Any = _SceneRenderer(scene)
        info.update({"iso": iso, "iso_units": volume.units_label, "surface": result.stats})
    elif mode.kind == "compare" and mode.measure == "surface-distance":
        iso = settings.iso if settings.iso is not None else default_iso(volume)
        result = surface_distance(volume, mode.test, mode.reference, iso, progress=progress)
        scene = OffscreenScene((width, height), settings.background)
        actor, bar = distance_actor(result.polydata, volume, DISTANCE_ARRAY)
        scene.add(actor)
        scene.renderer.AddViewProp(bar)
        runner = _SceneRenderer(scene)
        info.update({"iso": iso, "iso_units": volume.units_label, "surface": result.stats})
    elif mode.kind == "compare":
        reference = OffscreenScene((width, height), settings.background)
        reference.add(volume_prop(volume, transfer_function, mapper=get_mode(mode.reference).mapper,
                                  sample_distance=step, shading=transfer_function.shading.enabled))
        options = dict(settings.options)
        if settings.sample_distance is not None:
            options["step"] = settings.sample_distance
        renderer = get_mode(mode.test).create(volume, transfer_function, options)
        runner = _DifferenceRenderer(renderer, reference, volume, (width, height), settings.background)
        info["sample_distance_mm"] = step
    elif mode.kind == "volume":
        scene = OffscreenScene((width, height), settings.background)
        scene.add(volume_prop(volume, transfer_function, mapper=mode.mapper, sample_distance=step,
                              shading=transfer_function.shading.enabled))
        runner = _SceneRenderer(scene)
        info["sample_distance_mm"] = step
    else:
        options = dict(settings.options)
        if settings.sample_distance is not None:
            options["step"] = settings.sample_distance
        gl = options.get("compositing") == "gl"
        if gl:
            options["compositing"] = "float"  # the slices; OpenGL's framebuffer does the compositing
        renderer = mode.create(volume, transfer_function, options)
        if gl:
            runner = _SliceStackRenderer(renderer, volume, (width, height), settings.background)
        else:
            runner = _ImageRenderer(renderer, volume, (width, height), settings.background)
        info["options"] = {k: v for k, v in settings.options.items()}
    try:
        first = runner.frame(camera)
        setup_seconds = time.perf_counter() - start
        image = runner.capture()
        if first is not None and getattr(first, "stats", None):
            info["frame_stats"] = dict(first.stats)
        if isinstance(runner, _DifferenceRenderer):
            info["comparison"] = dict(runner.difference.numbers)
        if settings.frames:
            cameras = turning_cameras(camera, settings.frames)
            times = []
            for index, frame_camera in enumerate(cameras):
                tick = time.perf_counter()
                runner.frame(frame_camera)
                times.append(time.perf_counter() - tick)
                if progress is not None:
                    progress((index + 1) / len(cameras))
            info.update(FrameTimes(setup_seconds, times).summary())
        else:
            info["setup_seconds"] = setup_seconds
    finally:
        runner.close()
    return RenderReport(image, info)


def write_png(image: np.ndarray, path, *, overwrite: bool = False) -> Path:
    """Write an ``(h, w, 3|4)`` uint8 image (row 0 at the top) as PNG, atomically."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkIOImage import vtkPNGWriter

    path = Path(path).expanduser()
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: screenshots are written as PNG; use a .png file name")
    image = np.ascontiguousarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"expected an (h, w, 3|4) uint8 image, got {image.dtype} {image.shape}")
    height, width, channels = image.shape
    vtk_image = vtkImageData()
    vtk_image.SetDimensions(width, height, 1)
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(image[::-1]).reshape(-1, channels), deep=True)
    vtk_image.GetPointData().SetScalars(array)
    with atomic_output(path, overwrite=overwrite) as temporary:
        writer = vtkPNGWriter()
        writer.SetFileName(str(temporary))
        writer.SetInputData(vtk_image)
        writer.Write()
    return path


def read_png(path) -> np.ndarray:
    """A PNG as ``(h, w, channels)`` uint8, row 0 at the top."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkIOImage import vtkPNGReader

    from algorithms._vtk import run_algorithm

    reader = vtkPNGReader()
    reader.SetFileName(str(path))
    image = run_algorithm(reader)
    width, height, _ = image.GetDimensions()
    scalars = image.GetPointData().GetScalars()
    pixels = numpy_support.vtk_to_numpy(scalars).reshape(height, width, scalars.GetNumberOfComponents())
    return np.ascontiguousarray(pixels[::-1])


def parse_background(values: Sequence[float]) -> tuple[float, float, float]:
    """Background colour from three numbers, either all in [0, 1] or 0-255 integers."""
    if len(values) != 3:
        raise ValueError(f"a background colour needs three values (R G B), got {len(values)}")
    if any(v < 0 for v in values) or any(v > 255 for v in values):
        raise ValueError(f"background values must lie in [0, 1] or [0, 255], got {list(values)}")
    scale = 255.0 if any(v > 1 for v in values) else 1.0
    return tuple(float(v) / scale for v in values)


def options_from_mapping(mode_name: str, values: Mapping[str, Any]) -> dict[str, Any]:
    """Keep only the options the image mode declares (the command line passes all of its optional flags)."""
    mode = get_mode(mode_name)
    allowed = set(getattr(mode, "options", ()))
    return {k: v for k, v in values.items() if v is not None and k in allowed}
