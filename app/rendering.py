"""Headless rendering: cameras, VTK props for volumes and surfaces, off-screen scenes and frame timing.

The workbench's views and ``voxelscope render`` build their VTK props with the same functions here, so a mode
looks the same on screen and in a PNG.

Frames of reference: volumes and surfaces are built in the *volume frame* (index times spacing, mm) and placed in
the patient's LPS space by their prop's user matrix (``Volume.local_to_world``). That works for every mapper,
including those that ignore an image's direction matrix. Cameras are always in world (LPS) coordinates.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from algorithms._vtk import vtk_matrix
from algorithms.camera import Camera

from .volume import Volume

DEFAULT_SIZE = (512, 512)
DEFAULT_VIEW_ANGLE = 30.0

#: Camera presets in LPS: name -> (direction of projection, view up). "anterior" looks at the patient's face.
STANDARD_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "anterior": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "posterior": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "left": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "right": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "superior": ((0.0, 0.0, -1.0), (0.0, -1.0, 0.0)),
    "inferior": ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),
}


def bounding_radius(volume: Volume) -> float:
    """Half the diagonal of the volume's box (voxel edges included), in mm."""
    return 0.5 * float(np.linalg.norm(np.asarray(volume.dimensions) * np.asarray(volume.spacing)))


def default_camera(
    volume: Volume,
    *,
    view: str = "anterior",
    azimuth: float = 0.0,
    elevation: float = 0.0,
    parallel: bool = False,
    aspect: float = 1.0,
    view_angle: float = DEFAULT_VIEW_ANGLE,
) -> Camera:
    """A camera looking at the volume centre from a standard side (default: anterior), the whole box in view.

    ``azimuth`` and ``elevation`` (degrees) then orbit it like ``vtkCamera.Azimuth``/``Elevation``. ``aspect`` is
    the image's width / height; the fit accounts for it.
    """
    if view not in STANDARD_VIEWS:
        raise ValueError(f"unknown view {view!r}; choose one of {', '.join(STANDARD_VIEWS)}")
    direction, view_up = (np.asarray(v) for v in STANDARD_VIEWS[view])
    centre = volume.centre
    radius = bounding_radius(volume)
    half_angle = math.radians(view_angle) / 2
    if aspect < 1.0:  # the horizontal field of view is the narrower one
        half_angle = math.atan(math.tan(half_angle) * aspect)
    distance = radius / math.sin(half_angle)
    scale = radius / min(1.0, aspect)
    camera = Camera(
        position=tuple(centre - direction * distance),
        focal_point=tuple(centre),
        view_up=tuple(view_up),
        view_angle=view_angle,
        parallel_projection=parallel,
        parallel_scale=scale,
    )
    return camera.orbited(azimuth, elevation) if (azimuth or elevation) else camera


# ------------------------------------------------------------------------------------------------------------
# Props
# ------------------------------------------------------------------------------------------------------------
def default_sample_distance(volume: Volume) -> float:
    """Half the smallest voxel spacing (mm): the step both our ray marcher and VTK's mappers use by default."""
    return 0.5 * min(volume.spacing)


def volume_prop(volume: Volume, transfer_function, *, mapper: str = "gpu", sample_distance: float | None = None,
                shading: bool | None = None, image=None):
    """A ``vtkVolume`` of ``volume`` with VTK's GPU or CPU (fixed-point) ray-cast mapper.

    The sample distance is fixed (automatic adjustment off) so VTK and our renderers sample alike; ``image`` may
    pass an already converted ``volume.to_vtk(local=True)`` to share it between views.
    """
    from vtkmodules.vtkRenderingCore import vtkVolume
    from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper, vtkGPUVolumeRayCastMapper
    import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401 - registers the OpenGL GPU mapper

    step = sample_distance if sample_distance is not None else default_sample_distance(volume)
    if step <= 0:
        raise ValueError(f"sample distance must be positive (mm), got {step}")
    image = image if image is not None else volume.to_vtk(local=True)
    if mapper == "gpu":
        vtk_mapper = vtkGPUVolumeRayCastMapper()
        vtk_mapper.SetAutoAdjustSampleDistances(0)
        vtk_mapper.SetLockSampleDistanceToInputSpacing(0)
        vtk_mapper.SetSampleDistance(step)
        vtk_mapper.SetUseJittering(0)
    elif mapper == "cpu":
        vtk_mapper = vtkFixedPointVolumeRayCastMapper()
        vtk_mapper.SetAutoAdjustSampleDistances(0)
        vtk_mapper.SetSampleDistance(step)
        vtk_mapper.SetInteractiveSampleDistance(step)
        vtk_mapper.SetImageSampleDistance(1.0)
    else:
        raise ValueError(f"mapper must be 'gpu' or 'cpu', got {mapper!r}")
    vtk_mapper.SetInputData(image)
    vtk_mapper.SetBlendModeToComposite()
    prop = vtkVolume()
    prop.SetMapper(vtk_mapper)
    prop.SetProperty(transfer_function.to_vtk_property(shading=shading))
    prop.SetUserMatrix(vtk_matrix(volume.local_to_world))
    return prop


def surface_actor(polydata, volume: Volume, *, color=(0.9, 0.85, 0.75), flat: bool = False, opacity: float = 1.0,
                  scalars: str | None = None, scalar_range=None, lookup_table=None):
    """A ``vtkActor`` for a surface built in the volume frame, placed by the volume's ``local_to_world``."""
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

    mapper = vtkPolyDataMapper()
    mapper.SetInputData(polydata)
    if scalars:
        mapper.SetScalarModeToUsePointFieldData()
        mapper.SelectColorArray(scalars)
        mapper.ScalarVisibilityOn()
        if scalar_range is not None:
            mapper.SetScalarRange(*scalar_range)
        if lookup_table is not None:
            mapper.SetLookupTable(lookup_table)
    else:
        mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*color)
    prop.SetOpacity(opacity)
    prop.SetAmbient(0.15)
    prop.SetDiffuse(0.8)
    prop.SetSpecular(0.2)
    prop.SetSpecularPower(20)
    if flat:
        prop.SetInterpolationToFlat()
    actor.SetUserMatrix(vtk_matrix(volume.local_to_world))
    return actor


def distance_actor(polydata, volume: Volume, array: str, *, top: float | None = None):
    """A surface coloured by a point array of distances (mm): blue at 0, white halfway, red at ``top``
    (default: the 99th percentile). Returns the actor and a ``vtkScalarBarActor`` titled with the units."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
    from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

    if top is None:
        distances = numpy_support.vtk_to_numpy(polydata.GetPointData().GetArray(array))
        top = float(np.percentile(distances, 99)) if distances.size else 1.0
    top = max(top, 1e-6)
    colors = vtkColorTransferFunction()
    colors.AddRGBPoint(0.0, 0.23, 0.30, 0.75)
    colors.AddRGBPoint(0.5 * top, 0.87, 0.87, 0.87)
    colors.AddRGBPoint(top, 0.71, 0.02, 0.15)
    actor = surface_actor(polydata, volume, scalars=array, scalar_range=(0.0, top), lookup_table=colors)
    bar = vtkScalarBarActor()
    bar.SetLookupTable(colors)
    bar.SetTitle("distance (mm)")
    bar.SetNumberOfLabels(3)
    bar.SetWidth(0.08)
    bar.SetHeight(0.5)
    bar.SetPosition(0.9, 0.25)
    return actor, bar


# ------------------------------------------------------------------------------------------------------------
# Off-screen scene
# ------------------------------------------------------------------------------------------------------------
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

    def render(self) -> float:
        """Render one frame; returns its wall-clock seconds (the GL pipeline is flushed before timing ends)."""
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


def render_vtk_volume(volume: Volume, camera: Camera, transfer_function, *, mapper: str = "gpu",
                      size: Sequence[int] = DEFAULT_SIZE, sample_distance: float | None = None,
                      shading: bool | None = False, background=(0.0, 0.0, 0.0)) -> np.ndarray:
    """One off-screen frame of VTK's GPU or CPU ray caster as ``(h, w, 3)`` uint8 (row 0 at the top)."""
    scene = OffscreenScene(size, background)
    try:
        scene.add(volume_prop(volume, transfer_function, mapper=mapper, sample_distance=sample_distance, shading=shading))
        scene.set_camera(camera)
        scene.render()
        return scene.capture()
    finally:
        scene.close()


# ------------------------------------------------------------------------------------------------------------
# Frame timing
# ------------------------------------------------------------------------------------------------------------
@dataclass
class FrameTimes:
    """Per-frame seconds of a turning-camera sequence plus the one-off set-up."""

    setup_seconds: float
    frames: list[float]

    def summary(self) -> dict[str, float]:
        from .bench.common import Timing

        timing = Timing(self.frames)
        return {
            "setup_seconds": self.setup_seconds,
            "frame_seconds": timing.median,
            "mean_frame_seconds": timing.mean,
            "weighted_mean_frame_seconds": timing.weighted_mean,
            "p95_frame_seconds": timing.p95,
            "frames": len(self.frames),
        }


def turning_cameras(camera: Camera, frames: int, step_degrees: float = 2.0) -> list[Camera]:
    """``frames`` cameras turning by ``step_degrees`` azimuth each, starting one step after ``camera``."""
    if frames < 1:
        raise ValueError(f"frames must be at least 1, got {frames}")
    return [camera.orbited(azimuth=step_degrees * (i + 1)) for i in range(frames)]


def time_frames(render_frame: Callable[[Camera], object], cameras: Sequence[Camera]) -> list[float]:
    """Call ``render_frame(camera)`` for each camera and return wall-clock seconds per call."""
    times = []
    for camera in cameras:
        start = time.perf_counter()
        render_frame(camera)
        times.append(time.perf_counter() - start)
    return times
