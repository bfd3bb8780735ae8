"""One 3D view of the workbench: a header (render-mode chooser, live statistics) above a PyVista Qt view.

What the view shows comes from ``app``: surfaces from :func:`app.meshing.extract_surface` (in a worker, with a
reduced-resolution preview while the isovalue is dragged), VTK volumes from :func:`app.rendering.volume_prop`,
and our software renderers' images (rendered in a worker, reduced resolution while the camera moves, full
resolution once it rests) drawn as the view's background, so the camera stays interactive. Nothing is computed
on the GUI thread beyond building props and drawing.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any

import numpy as np
from pyvistaqt import QtInteractor
from qtpy.QtCore import QTimer, Signal
from qtpy.QtWidgets import QComboBox, QFrame, QHBoxLayout, QLabel, QSizePolicy, QVBoxLayout

from algorithms.camera import Camera
from app.bench.common import Timing
from app.compare import DISTANCE_ARRAY, image_difference, surface_distance
from app.meshing import extract_surface
from app.modes import get_mode, mode_names
from app.render_job import surface_color
from app.rendering import OffscreenScene, default_sample_distance, distance_actor, surface_actor, volume_prop
from app.volume import Volume

from .tasks import Task, TaskRunner

IDLE_MILLISECONDS = 250  # camera at rest this long -> full-quality frame
PREVIEW_SCALE = 3  # image modes render 1/3 of the pixels per side while the camera moves
INTERACTIVE_UPDATE_RATE = 8.0  # frames per second VTK's volume mappers aim for while the camera moves
STILL_UPDATE_RATE = 0.0001


def _format_bytes(count: float) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if count < 1024 or unit == "GB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024.0
    return f"{count:.1f} GB"


def _orientation_cube():
    """An annotated cube labelled with the LPS directions: L/R on x, P/A on y, S/I on z."""
    from vtkmodules.vtkRenderingAnnotation import vtkAnnotatedCubeActor

    cube = vtkAnnotatedCubeActor()
    cube.SetXPlusFaceText("L")
    cube.SetXMinusFaceText("R")
    cube.SetYPlusFaceText("P")
    cube.SetYMinusFaceText("A")
    cube.SetZPlusFaceText("S")
    cube.SetZMinusFaceText("I")
    cube.SetFaceTextScale(0.65)
    cube.GetCubeProperty().SetColor(0.25, 0.3, 0.4)
    cube.GetTextEdgesProperty().SetColor(0.8, 0.8, 0.8)
    for prop in (cube.GetXPlusFaceProperty(), cube.GetXMinusFaceProperty()):
        prop.SetColor(1.0, 0.6, 0.6)
    for prop in (cube.GetYPlusFaceProperty(), cube.GetYMinusFaceProperty()):
        prop.SetColor(0.6, 1.0, 0.6)
    for prop in (cube.GetZPlusFaceProperty(), cube.GetZMinusFaceProperty()):
        prop.SetColor(0.6, 0.7, 1.0)
    return cube


class RenderView(QFrame):
    """A view showing the volume in one render mode."""

    mode_chosen = Signal(int, str)  # index, mode name (the user picked it in the header)
    ready = Signal(int)  # a full-quality frame of the current content is on screen
    activated = Signal(int)  # the user clicked into this view
    failed = Signal(str)  # a message for the user

    def __init__(self, index: int, tasks: TaskRunner, parent=None) -> None:
        super().__init__(parent)
        self.index = index
        self.tasks = tasks
        self.setFrameShape(QFrame.StyledPanel)
        self.setObjectName(f"view{index}")

        self.mode_box = QComboBox()
        for name in mode_names():
            self.mode_box.addItem(get_mode(name).label, name)
        self.mode_box.setToolTip("Render mode of this view")
        self.mode_box.activated.connect(lambda _: self.mode_chosen.emit(self.index, self.mode_box.currentData()))
        self.stats_label = QLabel("")
        self.stats_label.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Preferred)
        self.stats_label.setObjectName("stats")
        header = QHBoxLayout()
        header.setContentsMargins(4, 2, 4, 2)
        header.addWidget(self.mode_box)
        header.addWidget(self.stats_label, 1)

        self.plotter = QtInteractor(self, auto_update=False, multi_samples=0)
        self.plotter.set_background("black")
        self.renderer = self.plotter.renderer
        self.plotter.add_orientation_widget(_orientation_cube(), interactive=False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(1, 1, 1, 1)
        layout.setSpacing(0)
        layout.addLayout(header)
        layout.addWidget(self.plotter.interactor, 1)

        self.volume: Volume | None = None
        self.image = None  # the shared vtkImageData of the volume (volume frame)
        self.mode = ""
        self.iso = 0.0
        self.transfer_function = None
        self.prop = None  # actor or volume on show
        self.surface = None  # SurfaceResult of the last full-resolution extraction
        self.surface_step = 1
        self.image_renderer = None
        self._reference_scene: OffscreenScene | None = None  # VTK's rendering in an image comparison
        self._scalar_bar = None
        self._content_task: Task | None = None
        self._frame_task: Task | None = None
        self._frame_wanted: tuple[int, int] | None = None
        self._frame_times: deque[float] = deque(maxlen=60)
        self._last_frame = 0.0
        self._content_stats = ""
        self._is_ready = False
        self._background_texture = None
        self._idle = QTimer(self)
        self._idle.setSingleShot(True)
        self._idle.setInterval(IDLE_MILLISECONDS)
        self._idle.timeout.connect(self._camera_rested)
        window = self.plotter.ren_win
        window.AddObserver("StartEvent", self._render_started)
        window.AddObserver("EndEvent", self._render_ended)
        self._render_start = 0.0
        self.plotter.interactor.installEventFilter(self)

    # -- public API used by the main window -------------------------------------------------------------------
    @property
    def is_ready(self) -> bool:
        return self._is_ready

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        from qtpy.QtCore import QEvent

        if event.type() == QEvent.MouseButtonPress:
            self.activated.emit(self.index)
        elif event.type() == QEvent.Resize and self.volume is not None and self.mode and self._shows_image():
            # Our images are rendered at the view's pixel size: a resized view gets a new frame once it settles.
            self._mark_not_ready()
            self._idle.start()
        return False

    def set_volume(self, volume: Volume, image, mode: str, iso: float, transfer_function) -> None:
        """Show a new volume (``image`` is its shared ``vtkImageData`` in the volume frame)."""
        self.volume = volume
        self.image = image
        self.iso = iso
        self.transfer_function = transfer_function
        self._set_mode(mode, force=True)

    def set_mode(self, mode: str) -> None:
        self._set_mode(mode, force=False)

    def set_iso(self, iso: float, *, preview: bool = False) -> None:
        self.iso = iso
        if self.volume is not None and self._shows_surface():
            self._build_surface(step=2 if preview else 1)

    def _shows_surface(self) -> bool:
        mode = get_mode(self.mode)
        return mode.kind == "surface" or (mode.kind == "compare" and mode.measure == "surface-distance")

    def _shows_image(self) -> bool:
        mode = get_mode(self.mode)
        return mode.kind == "image" or (mode.kind == "compare" and mode.measure == "image-difference")

    def set_transfer_function(self, transfer_function) -> None:
        self.transfer_function = transfer_function
        if self.volume is None:
            return
        kind = get_mode(self.mode).kind
        if kind == "volume" and self.prop is not None:
            self.prop.SetProperty(transfer_function.to_vtk_property())
            self._mark_not_ready()
            self.render(still=True)
        elif self._shows_image():
            self._build_image_renderer()

    def camera_moved(self) -> None:
        """The camera this view shows was changed (here or in a linked view)."""
        if self.volume is None:
            return
        self._mark_not_ready()
        if self._shows_image():
            self._request_frame(preview=True)
        else:
            self.render(still=False)
        self._idle.start()

    def render(self, *, still: bool = True) -> None:
        """Draw now; ``still=False`` lets VTK's volume mappers trade quality for speed (camera in motion)."""
        self.plotter.ren_win.SetDesiredUpdateRate(STILL_UPDATE_RATE if still else INTERACTIVE_UPDATE_RATE)
        self.renderer.ResetCameraClippingRange()
        self.plotter.render()
        if still and self._content_complete():
            self._set_ready()

    def capture(self) -> np.ndarray:
        """The view's current frame as ``(h, w, 3)`` uint8, row 0 at the top."""
        image = self.plotter.screenshot(return_img=True)
        return np.ascontiguousarray(image[..., :3])

    def current_surface(self):
        """The full-resolution surface on show (SurfaceResult), or None."""
        if get_mode(self.mode).kind == "surface" and self.surface is not None and self.surface_step == 1:
            return self.surface
        return None

    def shutdown(self) -> None:
        for task in (self._content_task, self._frame_task):
            if task is not None:
                task.cancel()
        self._idle.stop()
        self._close_reference()
        self.plotter.close()

    # -- content ------------------------------------------------------------------------------------------------
    def _set_mode(self, mode: str, *, force: bool) -> None:
        if mode == self.mode and not force:
            return
        self.mode = mode
        position = self.mode_box.findData(mode)
        if position >= 0:
            self.mode_box.setCurrentIndex(position)
        self._clear()
        if self.volume is None:
            return
        if self._shows_surface():
            self._build_surface(step=1)
        elif self._shows_image():
            self._build_image_renderer()
        else:
            self._build_volume_prop()

    def _clear(self) -> None:
        for task in (self._content_task, self._frame_task):
            if task is not None:
                task.cancel()
        self._content_task = self._frame_task = None
        self._frame_wanted = None
        if self.prop is not None:
            self.renderer.RemoveViewProp(self.prop)
        self.prop = None
        self.surface = None
        self.image_renderer = None
        self._close_reference()
        if self._scalar_bar is not None:
            self.renderer.RemoveViewProp(self._scalar_bar)
            self._scalar_bar = None
        self.renderer.TexturedBackgroundOff()
        self._frame_times.clear()
        self._content_stats = ""
        self._mark_not_ready()
        self._update_stats()

    def _close_reference(self) -> None:
        if self._reference_scene is not None:
            self._reference_scene.close()
            self._reference_scene = None

    def _content_complete(self) -> bool:
        if not self.mode:
            return False
        if self._shows_surface():
            return self.prop is not None and self.surface_step == 1 and self._content_task is None
        if get_mode(self.mode).kind == "volume":
            return self.prop is not None
        return False  # image modes signal readiness when a full-resolution frame arrives

    def _build_volume_prop(self) -> None:
        mode = get_mode(self.mode)
        step = default_sample_distance(self.volume)
        self.prop = volume_prop(self.volume, self.transfer_function, mapper=mode.mapper, sample_distance=step,
                                image=self.image)
        # In the workbench VTK may coarsen sampling while the camera moves (desired update rate), never at rest.
        self.prop.GetMapper().SetAutoAdjustSampleDistances(1)
        self.renderer.AddVolume(self.prop)
        self._content_stats = f"sample step {step:.2f} mm"
        self._update_stats()
        self.render(still=True)

    def _build_surface(self, *, step: int) -> None:
        if self._content_task is not None:
            self._content_task.cancel()
        volume, mode, iso = self.volume, get_mode(self.mode), self.iso
        source = volume if step == 1 else _subsampled(volume, step)
        label = f"{mode.label} at {iso:g} {volume.units_label}"
        if mode.kind == "compare":
            task = Task(label, surface_distance, source, mode.test, mode.reference, iso)
        else:
            task = Task(label, extract_surface, source, mode.name, iso)
        task.finished.connect(lambda result, task=task, step=step: self._surface_ready(task, result, step))
        task.failed.connect(lambda exc, task=task: self._content_failed(task, exc))
        task.cancelled.connect(lambda task=task: self._content_cancelled(task))
        self._content_task = task
        self._mark_not_ready()
        self.tasks.start(task)

    def _surface_ready(self, task: Task, result, step: int) -> None:
        if task is not self._content_task:
            return  # superseded
        self._content_task = None
        if self.prop is not None:
            self.renderer.RemoveViewProp(self.prop)
        self.surface, self.surface_step = result, step
        mode = get_mode(self.mode)
        stats = result.stats
        preview = f" (preview at 1/{step} resolution)" if step > 1 else ""
        if DISTANCE_ARRAY in stats or result.polydata.GetPointData().GetArray(DISTANCE_ARRAY) is not None:
            self.prop = self._distance_actor(result)
            self._content_stats = (
                f"distance to {get_mode(mode.reference).label}: Hausdorff {stats['hausdorff_mm']:.3f} mm, "
                f"mean {stats['mean_mm']:.4f} mm, 95 % {stats['p95_mm']:.3f} mm{preview}"
            )
        else:
            self.prop = surface_actor(result.polydata, self.volume, color=surface_color(self.volume, self.iso),
                                      flat=getattr(mode, "flat_shading", False))
            self._content_stats = (
                f"{stats['points']:,} points, {stats['triangles']:,} triangles, {stats['strips']:,} strips, "
                f"{_format_bytes(stats['bytes'])}, built in {stats['seconds']:.2f} s{preview}"
            )
        self.renderer.AddActor(self.prop)
        self._update_stats()
        self.render(still=True)

    def _distance_actor(self, result):
        """The surface coloured by its distance to the reference, with a colour bar in mm."""
        actor, bar = distance_actor(result.polydata, self.volume, DISTANCE_ARRAY)
        if self._scalar_bar is not None:
            self.renderer.RemoveViewProp(self._scalar_bar)
        self._scalar_bar = bar
        self.renderer.AddViewProp(bar)
        return actor

    def _build_image_renderer(self) -> None:
        if self._content_task is not None:
            self._content_task.cancel()
        mode = get_mode(self.mode)
        volume, function = self.volume, self.transfer_function
        renderer_mode = get_mode(mode.test) if mode.kind == "compare" else mode
        options: dict[str, Any] = {}
        if mode.kind == "compare":
            self._close_reference()
            reference = get_mode(mode.reference)
            self._reference_scene = OffscreenScene((64, 64), self.renderer.GetBackground())
            self._reference_scene.add(volume_prop(volume, function, mapper=reference.mapper,
                                                  sample_distance=default_sample_distance(volume), image=self.image))

        def create(progress=None):
            return renderer_mode.create(volume, function, options)

        task = Task(f"{mode.label}: set-up", create)
        task.finished.connect(lambda renderer, task=task: self._image_renderer_ready(task, renderer))
        task.failed.connect(lambda exc, task=task: self._content_failed(task, exc))
        task.cancelled.connect(lambda task=task: self._content_cancelled(task))
        self._content_task = task
        self._mark_not_ready()
        self.tasks.start(task)

    def _image_renderer_ready(self, task: Task, renderer) -> None:
        if task is not self._content_task:
            return
        self._content_task = None
        self.image_renderer = renderer
        self._request_frame(preview=False)

    def _content_failed(self, task: Task, exc: Exception) -> None:
        if task is self._content_task:
            self._content_task = None
            self._content_stats = "failed"
            self._update_stats()
            self.failed.emit(f"{task.label} failed: {exc}")

    def _content_cancelled(self, task: Task) -> None:
        if task is self._content_task:
            self._content_task = None
            self._content_stats = "cancelled"
            self._update_stats()

    # -- software-rendered frames ---------------------------------------------------------------------------
    def _viewport_pixels(self) -> tuple[int, int]:
        width, height = self.plotter.ren_win.GetSize()
        return max(int(width), 8), max(int(height), 8)

    def _request_frame(self, *, preview: bool) -> None:
        if self.image_renderer is None:
            return
        width, height = self._viewport_pixels()
        if preview:
            width, height = max(width // PREVIEW_SCALE, 8), max(height // PREVIEW_SCALE, 8)
        self._frame_wanted = (width, height)
        if self._frame_task is None:
            self._start_frame()

    def _start_frame(self) -> None:
        if self._frame_wanted is None or self.image_renderer is None:
            return
        width, height = self._frame_wanted
        self._frame_wanted = None
        full = (width, height) == self._viewport_pixels()
        world_camera = Camera.from_vtk(self.renderer.GetActiveCamera())
        if getattr(get_mode(self.mode), "parallel_only", False):
            # Shear-warp needs parallel projection: show the linked perspective view's focal plane in parallel.
            world_camera = world_camera.as_parallel()
        local_camera = world_camera.transformed(np.linalg.inv(self.volume.local_to_world))
        renderer = self.image_renderer
        background = self.renderer.GetBackground()
        reference = None
        if self._reference_scene is not None:
            # VTK's image is rendered here, on the GUI thread (OpenGL); ours and the difference in the worker.
            self._reference_scene.window.SetSize(width, height)
            self._reference_scene.set_camera(world_camera)
            self._reference_scene.render()
            reference = self._reference_scene.capture()

        def frame(progress=None):
            result = renderer.render(local_camera, width, height, progress=progress)
            image = result.to_uint8(background)
            if reference is None:
                return image, dict(result.stats)
            difference = image_difference(image, reference, background=background)
            return difference.heatmap, {**difference.numbers, "seconds": result.stats.get("seconds", 0.0)}

        task = Task(f"{get_mode(self.mode).label}: frame", frame)
        task.finished.connect(lambda result, task=task, full=full: self._frame_ready(task, result, full))
        task.failed.connect(lambda exc, task=task: self._frame_failed(task, exc))
        task.cancelled.connect(lambda task=task: self._frame_done(task))
        self._frame_task = task
        self.tasks.start(task)

    def _frame_ready(self, task: Task, result, full: bool) -> None:
        if task is not self._frame_task:
            return
        image, stats = result
        self._show_image(image)
        seconds = float(stats.get("seconds", 0.0))
        self._frame_times.append(seconds)
        self._last_frame = seconds
        details = ", ".join(_format_stat(key, value) for key, value in stats.items() if key in _SHOWN_STATS)
        height, width = image.shape[:2]
        self._content_stats = f"{width}x{height} px" + (f", {details}" if details else "") + ("" if full else " (preview)")
        self._update_stats()
        self._frame_done(task)
        if full and self._frame_wanted is None and not self._idle.isActive():
            self._set_ready()

    def _frame_failed(self, task: Task, exc: Exception) -> None:
        if task is self._frame_task:
            self.failed.emit(f"{task.label} failed: {exc}")
        self._frame_done(task)

    def _frame_done(self, task: Task) -> None:
        if task is self._frame_task:
            self._frame_task = None
            self._start_frame()

    def _show_image(self, image: np.ndarray) -> None:
        from vtkmodules.util import numpy_support
        from vtkmodules.vtkCommonDataModel import vtkImageData
        from vtkmodules.vtkRenderingCore import vtkTexture

        height, width = image.shape[:2]
        data = vtkImageData()
        data.SetDimensions(width, height, 1)
        data.GetPointData().SetScalars(numpy_support.numpy_to_vtk(np.ascontiguousarray(image[::-1]).reshape(-1, 3), deep=True))
        texture = vtkTexture()
        texture.SetInputData(data)
        texture.InterpolateOn()
        self._background_texture = texture
        self.renderer.SetBackgroundTexture(texture)
        self.renderer.TexturedBackgroundOn()
        self.plotter.render()

    def _camera_rested(self) -> None:
        if self.volume is None:
            return
        if self._shows_image():
            self._request_frame(preview=False)
        else:
            self.render(still=True)

    # -- statistics and readiness -----------------------------------------------------------------------------
    def _render_started(self, *args) -> None:
        self._render_start = time.perf_counter()

    def _render_ended(self, *args) -> None:
        if self.mode and not self._shows_image():
            seconds = time.perf_counter() - self._render_start
            self._frame_times.append(seconds)
            self._last_frame = seconds
            self._update_stats()

    def _update_stats(self) -> None:
        parts = [self._content_stats] if self._content_stats else []
        if self._frame_times:
            weighted = Timing(list(self._frame_times)).weighted_mean
            parts.append(f"frame {self._last_frame * 1000:.0f} ms (weighted mean {weighted * 1000:.0f} ms)")
        self.stats_label.setText(" | ".join(parts))
        self.stats_label.setToolTip(self.stats_label.text())

    def _mark_not_ready(self) -> None:
        self._is_ready = False

    def _set_ready(self) -> None:
        if not self._is_ready:
            self._is_ready = True
            self.ready.emit(self.index)


_SHOWN_STATS = ("samples_per_ray", "early_terminated", "slices", "voxels_composited", "psnr_foreground", "rmse",
                "ssim")


def _format_stat(key: str, value: float) -> str:
    if key == "early_terminated":
        return f"{100 * value:.0f} % of rays terminated early"
    if key == "samples_per_ray":
        return f"{value:.1f} samples per ray"
    if key == "psnr_foreground":
        return f"PSNR {value:.1f} dB (foreground)"
    if key == "rmse":
        return f"RMSE {value:.4f}"
    if key == "ssim":
        return f"SSIM {value:.3f}"
    return f"{key.replace('_', ' ')} {value:.3g}"


def _subsampled(volume: Volume, step: int) -> Volume:
    """Every ``step``-th voxel along each axis, spacing scaled (for previews of any surface method)."""
    return Volume(
        np.ascontiguousarray(volume.array[::step, ::step, ::step]),
        spacing=tuple(s * step for s in volume.spacing),
        origin=volume.origin,
        direction=volume.direction,
        modality=volume.modality,
        units=volume.units,
        metadata=volume.metadata,
    )
