"""An off-screen VTK scene (EGL, OSMesa or X as available) that renders and reads pixels back, a scene without
any window for our software renderers, and PNG files.

The command line renders every mode into one of these through the same view pipeline the window uses. A mode whose
picture is its software renderer's frame alone (ray marching, shear-warp, slicing composited by us) needs no OpenGL
context: :class:`FrameScene` gives the pipeline a :class:`FrameRenderer` (a stand-in for ``vtkRenderer`` that
holds the camera and takes the frame) and captures the frame itself, which is the picture an OpenGL render of the
frame as the renderer's background reads back, pixel for pixel (issue 20: a Mesa context costs about 80 MiB of
resident memory, VTK's rendering module about 12 MiB).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkImageData

from algorithms.common.camera import Camera
from algorithms.common.vtk_bridge import run_algorithm

from ..io.atomic import atomic_output
from ..io.vtk_writing import write_with_vtk
from .props import volume_prop

DEFAULT_SIZE = (512, 512)


class OffscreenScene:
    """A renderer in an off-screen window (EGL/OSMesa/X as available) that renders and reads back pixels."""

    def __init__(self, size: Sequence[int] = DEFAULT_SIZE, background=(0.0, 0.0, 0.0)) -> None:
        from vtkmodules.vtkRenderingCore import vtkRenderer, vtkRenderWindow
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 - registers the OpenGL back end

        width, height = (int(v) for v in size)
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        self.renderer = vtkRenderer()
        self.renderer.SetBackground(*background)
        self.window = vtkRenderWindow()
        self.window.SetOffScreenRendering(1)
        self.window.SetSize(width, height)
        self.window.SetMultiSamples(0)
        self.window.AddRenderer(self.renderer)
        self.background = tuple(background)

    @property
    def size(self) -> tuple[int, int]:
        width, height = self.window.GetSize()
        return int(width), int(height)

    def add(self, prop) -> None:
        if prop.IsA("vtkVolume"):
            self.renderer.AddVolume(prop)
        else:
            self.renderer.AddActor(prop)

    def clear(self) -> None:
        self.renderer.RemoveAllViewProps()

    def set_camera(self, camera: Camera) -> None:
        camera.apply_to_vtk(self.renderer.GetActiveCamera())
        self.renderer.ResetCameraClippingRange()

    def camera(self) -> Camera:
        return Camera.from_vtk(self.renderer.GetActiveCamera())

    def set_size(self, width: int, height: int) -> None:
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        self.window.SetSize(int(width), int(height))

    def render(self) -> float:
        """Render one frame; returns its wall-clock seconds (the GL pipeline is flushed before timing ends)."""
        self.renderer.ResetCameraClippingRange()
        start = time.perf_counter()
        self.window.Render()
        self.window.WaitForCompletion()
        return time.perf_counter() - start

    def capture(self) -> np.ndarray:
        """The last rendered frame as ``(height, width, 3)`` uint8, row 0 at the top."""
        from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter

        grabber = vtkWindowToImageFilter()
        grabber.SetInput(self.window)
        grabber.SetInputBufferTypeToRGB()
        grabber.ReadFrontBufferOff()
        grabber.ShouldRerenderOff()
        grabber.Update()
        image = grabber.GetOutput()
        width, height, _ = image.GetDimensions()
        pixels = numpy_support.vtk_to_numpy(image.GetPointData().GetScalars()).reshape(height, width, 3)
        return np.ascontiguousarray(pixels[::-1])

    def close(self) -> None:
        self.clear()
        self.window.Finalize()


class FrameCamera:
    """The camera of a :class:`FrameRenderer`: what the view pipeline sets and reads of a ``vtkCamera`` (see
    :meth:`Camera.apply_to_vtk` and :meth:`Camera.from_vtk`), with ``vtkCamera``'s defaults and its handling of the
    values: view-up normalised (a zero vector gives +y), the view angle clamped to [1e-8, 179] degrees. So the
    frames' cameras read back the same doubles as from a ``vtkCamera`` (a test compares the two)."""

    def __init__(self) -> None:
        self._position = (0.0, 0.0, 1.0)
        self._focal_point = (0.0, 0.0, 0.0)
        self._view_up = (0.0, 1.0, 0.0)
        self._view_angle = 30.0
        self._parallel = 0
        self._parallel_scale = 1.0

    # vtkCamera's method names, so Camera.apply_to_vtk and Camera.from_vtk work on it unchanged.
    def SetPosition(self, x: float, y: float, z: float) -> None:
        self._position = (float(x), float(y), float(z))

    def SetFocalPoint(self, x: float, y: float, z: float) -> None:
        self._focal_point = (float(x), float(y), float(z))

    def SetViewUp(self, x: float, y: float, z: float) -> None:
        x, y, z = float(x), float(y), float(z)
        norm = math.sqrt(x * x + y * y + z * z)
        self._view_up = (x / norm, y / norm, z / norm) if norm != 0.0 else (0.0, 1.0, 0.0)

    def SetViewAngle(self, degrees: float) -> None:
        self._view_angle = min(max(float(degrees), 1e-8), 179.0)

    def SetParallelProjection(self, on: int) -> None:
        self._parallel = int(on)

    def SetParallelScale(self, scale: float) -> None:
        self._parallel_scale = float(scale)

    def GetPosition(self) -> tuple[float, float, float]:
        return self._position

    def GetFocalPoint(self) -> tuple[float, float, float]:
        return self._focal_point

    def GetViewUp(self) -> tuple[float, float, float]:
        return self._view_up

    def GetViewAngle(self) -> float:
        return self._view_angle

    def GetParallelProjection(self) -> int:
        return self._parallel

    def GetParallelScale(self) -> float:
        return self._parallel_scale


class FrameRenderer:
    """Stands in for the ``vtkRenderer`` of a :class:`FrameScene`: it holds the camera, the background and the
    frame on show, and draws nothing - no VTK rendering module is loaded (about 12 MiB) and no OpenGL context made
    (about 80 MiB). It has the few ``vtkRenderer`` methods the view pipeline calls for a content whose picture is
    its frame; adding a VTK prop is refused (such a mode renders in an :class:`OffscreenScene`)."""

    def __init__(self, background=(0.0, 0.0, 0.0)) -> None:
        self.camera = FrameCamera()
        self.background = tuple(float(v) for v in background)
        self.image: np.ndarray | None = None

    def show_frame(self, image: np.ndarray) -> None:
        """The content's frame, ``(h, w, 3)`` uint8 over the background, row 0 at the top."""
        self.image = image

    # -- the vtkRenderer methods the view pipeline calls ---------------------------------------------------------
    def GetActiveCamera(self) -> FrameCamera:
        return self.camera

    def AddObserver(self, event: str, callback) -> int:
        return 0  # it never renders, so no StartEvent or EndEvent

    def ResetCameraClippingRange(self) -> None:
        pass  # no depth buffer

    def SetBackground(self, r: float, g: float, b: float) -> None:
        self.background = (float(r), float(g), float(b))

    def TexturedBackgroundOff(self) -> None:
        self.image = None

    def SetBackgroundTexture(self, texture) -> None:
        if texture is not None:
            raise TypeError("a FrameRenderer takes frames through show_frame, not VTK textures")
        self.image = None

    def _refuse(self, prop) -> None:
        raise TypeError(f"a FrameRenderer draws no VTK props (got a {prop.GetClassName()}); render this mode in an "
                        "OffscreenScene")

    AddActor = AddVolume = AddViewProp = _refuse

    def RemoveViewProp(self, prop) -> None:
        pass  # none was added

    def RemoveAllViewProps(self) -> None:
        pass


class FrameScene:
    """A scene for contents whose picture is their own frame (``picture_is_frame``): a :class:`FrameRenderer`
    instead of a ``vtkRenderer`` in a window; :meth:`capture` returns the frame on show."""

    def __init__(self, size: Sequence[int] = DEFAULT_SIZE, background=(0.0, 0.0, 0.0)) -> None:
        width, height = (int(v) for v in size)
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        self.renderer = FrameRenderer(background)
        self.background = tuple(background)
        self._size = (width, height)

    @property
    def size(self) -> tuple[int, int]:
        return self._size

    def set_size(self, width: int, height: int) -> None:
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        self._size = (int(width), int(height))

    def render(self) -> float:
        """Nothing to draw: the pipeline made the frame when the camera or an input changed."""
        return 0.0

    def capture(self) -> np.ndarray:
        """The frame on show as ``(height, width, 3)`` uint8, row 0 at the top."""
        image = self.renderer.image
        if image is None:
            raise RuntimeError("no frame has been shown")
        if tuple(reversed(image.shape[:2])) != self._size:
            raise RuntimeError(f"the frame is {image.shape[1]} x {image.shape[0]} pixels, the scene "
                               f"{self._size[0]} x {self._size[1]}")
        return np.array(image[..., :3], dtype=np.uint8, copy=True)

    def close(self) -> None:
        self.renderer.image = None


def write_png(image: np.ndarray, path, *, overwrite: bool = False) -> Path:
    """Write an ``(h, w, 3|4)`` uint8 image (row 0 at the top) as PNG, atomically."""
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
        write_with_vtk(vtkPNGWriter, vtk_image, temporary)
    return path


def read_png(path) -> np.ndarray:
    """A PNG as ``(h, w, channels)`` uint8, row 0 at the top."""
    from vtkmodules.vtkIOImage import vtkPNGReader

    reader = vtkPNGReader()
    reader.SetFileName(str(path))
    image = run_algorithm(reader)
    width, height, _ = image.GetDimensions()
    scalars = image.GetPointData().GetScalars()
    pixels = numpy_support.vtk_to_numpy(scalars).reshape(height, width, scalars.GetNumberOfComponents())
    return np.ascontiguousarray(pixels[::-1])


def render_vtk_volume(volume, camera: Camera, transfer_function, *, mapper: str = "gpu",
                      size: Sequence[int] = DEFAULT_SIZE, sample_distance: float | None = None,
                      shading: bool | None = False, background=(0.0, 0.0, 0.0)) -> np.ndarray:
    """One off-screen frame of VTK's GPU or CPU ray caster as ``(h, w, 3)`` uint8 (row 0 at the top)."""
    scene = OffscreenScene(size, background)
    try:
        scene.add(volume_prop(volume, transfer_function, mapper=mapper, sample_distance=sample_distance,
                              shading=shading))
        scene.set_camera(camera)
        scene.render()
        return scene.capture()
    finally:
        scene.close()
