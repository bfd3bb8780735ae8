"""The view pipeline: one view's VTK pipeline for a scene item, a mode and its options, shared by the command line
and every window view.

:class:`ViewPipeline` owns a ``vtkRenderer`` (a window view's or an off-screen scene's) and keeps what it shows up to
date as its inputs change - the item, the mode and its options, the isovalue, the transfer function, the sample
distance, the camera - through the mode's content object (:mod:`app.pipeline.content`). Long work goes through the
:class:`~app.pipeline.jobs.JobRunner` the host gives it (a thread pool in the window, :class:`ImmediateRunner` on the
command line), so the same logic serves both:

- a newer request supersedes an older one (its result is dropped, the job cancelled);
- while the isovalue is dragged, surfaces are prepared with the mode's own coarse path
  (``Capabilities.preview_stride``) and refined when the drag ends;
- software renderers draw previews at a third of the pixels while the camera moves and a full frame once it rests
  (then further jitter passes of it, if the content asks for them: ``refining()``);
- ``ready`` is emitted when the full-quality picture of the current inputs is on the renderer.

The host listens to four signals: ``changed(still)`` (render the window now; ``still=False`` lets VTK's volume
mappers trade quality for speed), ``status(text)``, ``ready()``, ``failed(message)``.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import replace
from typing import Any, Callable, Mapping

from algorithms.common.camera import Camera

from ..events import Signal
from .content import REBUILD, REDRAW, REFRAME, Frame, ViewContent, ViewInputs
from .jobs import JobRunner
from .props import surface_actor, clear_background_image
from .timing import Timing

PREVIEW_SCALE = 3  # software renderers draw 1/3 of the pixels per side while the camera moves
MIN_FRAME_PIXELS = 8


class ViewPipeline:
    """One view's pipeline. ``viewport_size()`` returns the renderer's size in pixels (width, height)."""

    def __init__(self, renderer, runner: JobRunner, viewport_size: Callable[[], tuple[int, int]]) -> None:
        self.renderer = renderer
        self.runner = runner
        self.viewport_size = viewport_size
        self.changed = Signal()  # (still: bool)
        self.status = Signal()  # (text)
        self.ready = Signal()  # ()
        self.failed = Signal()  # (message)

        self.inputs: ViewInputs | None = None
        self.mode = None
        self.options: dict[str, Any] = {}
        self.content: ViewContent | None = None
        self.last_frame: Frame | None = None
        self.prepare_seconds = 0.0
        self._content_job = None  # handles of running jobs, to cancel them
        self._frame_job = None
        self._content_token = 0  # a job's result is used only if no newer request came since it started
        self._frame_token = 0
        self._content_busy = False
        self._frame_busy = False
        self._content_preview = False
        self._content_shown = False
        self._frame_wanted: tuple[int, int] | None = None
        self._frame_full = False
        self._moving = False
        self._is_ready = False
        self._frame_times: deque[float] = deque(maxlen=60)
        self._render_start = 0.0
        self._overlays: list = []
        renderer.AddObserver("StartEvent", self._render_started)
        renderer.AddObserver("EndEvent", self._render_ended)

    # -- inputs -------------------------------------------------------------------------------------------------------
    def set_inputs(self, inputs: ViewInputs, mode=None, options: Mapping[str, Any] | None = None) -> None:
        """Show a new item (with its isovalue, transfer function, ...), optionally in another mode (a
        :class:`~app.modes.base.Mode`; the registry resolves names) with ``options``: the content is built again,
        once."""
        if mode is not None:
            self.options = mode.resolve_options(options)
            self.mode = mode
        self.inputs = inputs
        self._rebuild_content()

    def set_mode(self, mode, options: Mapping[str, Any] | None = None) -> None:
        """Show ``mode`` (a :class:`~app.modes.base.Mode`) with ``options`` (validated by the mode)."""
        self.options = mode.resolve_options(options)
        self.mode = mode
        self._rebuild_content()

    def set_options(self, **values: Any) -> None:
        """Change some of the mode's options (the others keep their values)."""
        if self.mode is None:
            raise ValueError("choose a mode before setting its options")
        options = self.mode.resolve_options({**self.options, **values})
        if options != self.options:
            self.options = options
            self._rebuild_content()

    def set_iso(self, iso: float, *, preview: bool = False) -> None:
        """New isovalue; ``preview`` while it is being dragged (surfaces then use the mode's coarse path)."""
        if self.inputs is None:
            return
        self.inputs = replace(self.inputs, iso=float(iso))
        self._input_changed("iso", preview=preview)

    def set_transfer_function(self, function) -> None:
        if self.inputs is None:
            return
        self.inputs = replace(self.inputs, transfer_function=function)
        self._input_changed("transfer_function")

    def set_sample_distance(self, millimetres: float | None) -> None:
        if self.inputs is None:
            return
        if millimetres is not None and not millimetres > 0:
            raise ValueError(f"the sample distance must be a positive number of mm, got {millimetres}")
        self.inputs = replace(self.inputs, sample_distance=millimetres)
        self._input_changed("sample_distance")

    def set_tools(self, tools, evaluation: str = "binary", *, moving: bool = False) -> None:
        """New cut-away tools (LPS mm) or evaluation; ``moving`` while a tool is dragged: our renderers then draw
        previews without cut normals (the cheap path of source 002, 2.5.2) and surfaces their coarse path, and the
        final call with ``moving=False`` refines."""
        if self.inputs is None:
            return
        self.inputs = replace(self.inputs, tools=tuple(tools), cut_evaluation=evaluation, tools_moving=bool(moving))
        self._input_changed("cutaways", preview=moving)

    def set_overlays(self, items) -> None:
        """Show other items of the scene beside the content: meshes as translucent surfaces (patient coordinates).
        Items of other kinds are not drawn as overlays."""
        for actor in self._overlays:
            self.renderer.RemoveActor(actor)
        self._overlays = [surface_actor(item.polydata, None, color=(0.55, 0.75, 0.95), opacity=0.6)
                          for item in items if item.kind == "mesh"]
        for actor in self._overlays:
            self.renderer.AddActor(actor)
        self.changed.emit(True)

    def set_background(self, color: tuple[float, float, float]) -> None:
        self.renderer.SetBackground(*color)
        if self.inputs is not None:
            self.inputs = replace(self.inputs, background=tuple(color))
            self._input_changed("background")

    # -- camera and viewport ------------------------------------------------------------------------------------------
    def camera(self) -> Camera:
        """The renderer's camera (world, LPS mm)."""
        return Camera.from_vtk(self.renderer.GetActiveCamera())

    def set_camera(self, camera: Camera) -> None:
        """Move the camera (the command line's way; in the window the interactor moves it)."""
        camera.apply_to_vtk(self.renderer.GetActiveCamera())
        self.renderer.ResetCameraClippingRange()
        self.camera_moved(moving=False)

    def camera_moved(self, *, moving: bool = True) -> None:
        """The camera changed (here or in a linked view). ``moving`` while the user drags it."""
        if self.content is None:
            return
        self._moving = moving
        self._not_ready()
        if self.content.uses_frames:
            self._request_frame(preview=moving)
        else:
            self.changed.emit(not moving)
            self._check_ready()

    def camera_rested(self) -> None:
        """The camera has stopped moving: draw at full quality."""
        self._moving = False
        if self.content is None:
            return
        if self.content.uses_frames:
            self._request_frame(preview=False)
        else:
            self.changed.emit(True)
            self._check_ready()

    def viewport_resized(self) -> None:
        """The view's size changed; software renderers draw at the new size once the host calls
        :meth:`camera_rested` (when the size has settled)."""
        if self.content is not None and self.content.uses_frames:
            self._not_ready()

    # -- outputs ------------------------------------------------------------------------------------------------------
    @property
    def is_ready(self) -> bool:
        return self._is_ready

    @property
    def preparing(self) -> bool:
        """True while the content is being prepared (a surface extracted, a renderer set up...)."""
        return self._content_busy

    def surface(self):
        """The full-resolution surface on show (a ``SurfaceResult``, volume frame), or None."""
        if self.content is None or self._content_preview or not self._content_shown:
            return None
        return self.content.surface()

    def frame_times(self) -> list[float]:
        return list(self._frame_times)

    def shutdown(self) -> None:
        self._cancel_jobs()
        if self.content is not None:
            self.content.remove(self.renderer)
            self.content.close()
            self.content = None

    # -- content ------------------------------------------------------------------------------------------------------
    def _cancel_jobs(self) -> None:
        for job in (self._content_job, self._frame_job):
            if job is not None:
                job.cancel()
        self._content_job = self._frame_job = None
        self._content_token += 1  # results of jobs still running are dropped
        self._frame_token += 1
        self._content_busy = self._frame_busy = False
        self._frame_wanted = None

    def _rebuild_content(self) -> None:
        if self.inputs is None or self.mode is None:
            return
        self._cancel_jobs()
        if self.content is not None:
            self.content.remove(self.renderer)
            self.content.close()

        clear_background_image(self.renderer)
        accepted = self.mode.input
        kind = self.inputs.item.kind
        if not (accepted == kind or (accepted == "volume" and hasattr(self.inputs.item, "volume"))):
            self.content = None
            self._emit_status(f"{self.mode.label} shows a {accepted}; {self.inputs.item.name} is a {kind}")
            self.changed.emit(True)
            return
        self.content = self.mode.create_content(self.options)
        self.last_frame = None
        self._frame_times.clear()
        self._content_shown = False
        self._prepare(preview=False)

    def _input_changed(self, change: str, *, preview: bool = False) -> None:
        if self.content is None:
            return
        action = self.content.react(change, self.renderer, self.inputs)
        if action == REBUILD:
            self._prepare(preview=preview)
        elif action == REFRAME:
            self._not_ready()
            self._request_frame(preview=preview)
        elif action == REDRAW:
            self._not_ready()
            self.changed.emit(True)
            self._check_ready()

    def _prepare(self, *, preview: bool) -> None:
        self._content_token += 1
        token = self._content_token
        if self._content_job is not None:
            self._content_job.cancel()
            self._content_job = None
        content, inputs = self.content, self.inputs
        self._not_ready()
        self._content_busy = True
        self._content_preview = preview
        label = f"{self.mode.label} of {inputs.item.name}" + (" (preview)" if preview else "")
        started = time.perf_counter()

        def work(progress=None):
            return content.prepare(inputs, preview=preview, progress=progress)

        def current() -> bool:
            return token == self._content_token and content is self.content

        def done(prepared):
            if not current():
                return  # superseded by a newer request
            self._content_busy, self._content_job = False, None
            self.prepare_seconds = time.perf_counter() - started
            content.install(self.renderer, inputs, prepared)
            self._content_shown = True
            self._emit_status()
            if content.uses_frames:
                self._request_frame(preview=self._moving)
            else:
                self.changed.emit(True)
                self._check_ready()

        def failed(exc):
            if current():
                self._content_busy, self._content_job = False, None
                self._emit_status("failed")
                self.failed.emit(f"{label} failed: {exc}")

        def cancelled():
            if current():
                self._content_busy, self._content_job = False, None
                self._emit_status("cancelled")

        job = self.runner.submit(label, work, done=done, failed=failed, cancelled=cancelled)
        if current() and self._content_busy:
            self._content_job = job

    # -- frames -------------------------------------------------------------------------------------------------------
    def _request_frame(self, *, preview: bool) -> None:
        if self.content is None or not self.content.uses_frames or self._content_busy:
            return
        width, height = self.viewport_size()
        width, height = max(int(width), MIN_FRAME_PIXELS), max(int(height), MIN_FRAME_PIXELS)
        if preview:
            width = max(width // PREVIEW_SCALE, MIN_FRAME_PIXELS)
            height = max(height // PREVIEW_SCALE, MIN_FRAME_PIXELS)
        self._frame_wanted = (width, height)
        if not self._frame_busy:
            self._start_frame()

    def _start_frame(self) -> None:
        if self._frame_wanted is None or self.content is None:
            return
        size = self._frame_wanted
        self._frame_wanted = None
        viewport = self.viewport_size()
        full = size == (max(int(viewport[0]), MIN_FRAME_PIXELS), max(int(viewport[1]), MIN_FRAME_PIXELS))
        content = self.content
        try:
            work = content.frame_work(self.renderer, self.camera(), size)
        except ValueError as exc:
            self.failed.emit(f"{self.mode.label}: {exc}")
            return
        label = f"{self.mode.label}: frame"
        self._frame_token += 1
        token = self._frame_token
        self._frame_busy = True

        def current() -> bool:
            return token == self._frame_token and content is self.content

        def finish() -> None:
            self._frame_busy, self._frame_job = False, None

        def done(frame: Frame):
            if not current():
                return
            finish()
            content.show_frame(self.renderer, frame)
            self.last_frame = frame
            self._frame_full = full
            self._frame_times.append(frame.seconds)
            self._emit_status()
            self.changed.emit(True)
            if self._frame_wanted is None and full and not self._moving and self._refining():
                self._frame_wanted = size  # the next jitter pass of the same camera and size (accumulation)
            if self._frame_wanted is not None:
                self._start_frame()
            else:
                self._check_ready()

        def failed(exc):
            if current():
                finish()
                self.failed.emit(f"{label} failed: {exc}")
                self._start_frame()

        def cancelled():
            if current():
                finish()
                self._start_frame()

        job = self.runner.submit(label, work, done=done, failed=failed, cancelled=cancelled)
        if current() and self._frame_busy:
            self._frame_job = job

    # -- readiness and status -----------------------------------------------------------------------------------------
    def _not_ready(self) -> None:
        self._is_ready = False

    def _check_ready(self) -> None:
        if self._is_ready or self.content is None or self._moving:
            return
        if self._content_busy or self._content_preview or not self._content_shown:
            return
        if self.content.uses_frames and (self._frame_busy or self._frame_wanted is not None
                                         or self.last_frame is None or not self._frame_full or self._refining()):
            return
        self._is_ready = True
        self.ready.emit()

    def _refining(self) -> bool:
        """Whether the content wants more frames of the camera on show (jitter passes accumulated while idle)."""
        refining = getattr(self.content, "refining", None)
        return bool(refining is not None and refining())

    def _render_started(self, *args) -> None:
        self._render_start = time.perf_counter()

    def _render_ended(self, *args) -> None:
        if self.content is not None and not self.content.uses_frames:
            self._frame_times.append(time.perf_counter() - self._render_start)
            self._emit_status()

    def _emit_status(self, override: str | None = None) -> None:
        if override is not None:
            self.status.emit(override)
            return
        parts = []
        text = self.content.status() if self.content is not None else ""
        if text:
            parts.append(text + (" (preview)" if self._content_preview else ""))
        if self.content is not None and self.content.uses_frames and self.last_frame is not None:
            width, height = self.last_frame.size
            parts.append(f"{width}x{height} px" + ("" if self._frame_full else " (preview)"))
        if self._frame_times:
            times = list(self._frame_times)
            parts.append(f"frame {times[-1] * 1000:.0f} ms (weighted mean {Timing(times).weighted_mean * 1000:.0f} ms)")
        self.status.emit(" | ".join(parts))
