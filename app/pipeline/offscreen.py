"""An off-screen VTK scene (EGL, OSMesa or X as available) that renders and reads pixels back, and PNG files.

The command line renders every mode into one of these through the same view pipeline the window uses.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Sequence

import numpy as np

from algorithms.common.camera import Camera

from ..io.atomic import atomic_output

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
        from vtkmodules.util import numpy_support
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

    from algorithms.common.vtk_bridge import run_algorithm

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
    from .props import volume_prop

    scene = OffscreenScene(size, background)
    try:
        scene.add(volume_prop(volume, transfer_function, mapper=mapper, sample_distance=sample_distance,
                              shading=shading))
        scene.set_camera(camera)
        scene.render()
        return scene.capture()
    finally:
        scene.close()
