"""Our software renderers as view content: the item's image -> the mode's renderer filter -> one RGBA frame per
camera, shown as the view's background (so the camera, its linking and the overlays stay VTK's).

The filter (a :class:`algorithms.common.render_filter.RendererFilter`) keeps its set-up - classification,
encodings, gradients - between frames and rebuilds it only when its input, transfer table or a set-up option
changes; a frame costs one filter update. Frames are made off the owner thread (the filter is touched by one frame
job at a time) and composited over the view's background.

Accumulation while idle: with the mode option ``passes`` > 1, once a full-size frame of a camera is on show the
pipeline asks for more frames of the same camera and size (see :meth:`RendererContent.refining`); each renders the
next jitter pass (``SetPassIndex``) and shows the running mean of the passes so far, so a still view refines in
place and a moved camera starts again from pass 0. The passes are a pure function of camera and size, so the
command line (which renders every pass before it writes) and a window view show the same final frame.

Texture slicing drawn by OpenGL (``compositing=gl``) is the one software mode whose compositing happens in the
renderer: its slices and textures are made off the owner thread and handed to VTK actors on it.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from algorithms.common.camera import Camera
from algorithms.common.vtk_bridge import run_algorithm

from .cameras import camera_in_frame
from .content import IGNORE, REBUILD, REFRAME, Frame, ViewContent, ViewInputs
from .offscreen import FrameRenderer

#: Frame statistics shown in the view's header, in this order, and how.
_SHOWN_STATS = {
    "samples_per_ray": lambda v: f"{v:.1f} samples per ray",
    "early_terminated": lambda v: f"{100 * v:.0f} % of rays terminated early",
    "slices": lambda v: f"slices {v:.3g}",
    "voxels_composited": lambda v: f"voxels composited {v:.3g}",
    "passes": lambda v: f"{v:.0f} passes",
}


def frame_camera(mode, camera: Camera, inputs: ViewInputs) -> Camera:
    """The world camera as the mode's renderer needs it: in the item's volume frame, parallel if the mode
    renders in parallel only (a linked perspective view is then followed at its focal plane)."""
    if mode.capabilities.parallel_only:
        camera = camera.as_parallel()
    return camera_in_frame(camera, inputs.item.local_to_world)


def rgba_to_rgb(rgba: np.ndarray, background) -> np.ndarray:
    """An ``(h, w, 4)`` uint8 premultiplied image (row 0 at the top) over a background colour, as uint8 RGB.

    In float32, ``colour + (1 - alpha / 255) * background * 255`` rounded, in one work buffer (no temporaries).
    """
    back = np.asarray(background, dtype=np.float32).reshape(1, 1, 3) * 255.0
    transparency = rgba[..., 3:4].astype(np.float32)
    transparency /= 255.0
    np.subtract(1.0, transparency, out=transparency)
    out = np.multiply(transparency, back)
    out += rgba[..., :3]
    np.rint(out, out=out)
    np.clip(out, 0, 255, out=out)
    return out.astype(np.uint8)


def filter_frame(algorithm, camera: Camera, size: tuple[int, int], background, progress=None, *,
                 pass_index: int = 0) -> Frame:
    """Run a renderer filter for one camera (its input's frame), size and jitter pass; the frame over
    ``background``."""
    from vtkmodules.util import numpy_support

    algorithm.SetCamera(camera)
    algorithm.SetImageSize(*size)
    algorithm.SetPassIndex(pass_index)
    start = time.perf_counter()
    output = run_algorithm(algorithm, progress)
    seconds = time.perf_counter() - start
    width, height, _ = output.GetDimensions()
    rgba = numpy_support.vtk_to_numpy(output.GetPointData().GetScalars()).reshape(height, width, 4)[::-1]
    stats = dict(algorithm.last_stats)
    stats.setdefault("seconds", seconds)
    return Frame(rgba_to_rgb(rgba, background), stats, seconds)


def format_frame_stats(stats: dict[str, Any]) -> str:
    return ", ".join(show(stats[key]) for key, show in _SHOWN_STATS.items() if key in stats)


def _frame_key(camera: Camera, size: tuple[int, int], background) -> tuple:
    """What a frame depends on besides the filter's set-up: camera, size and background."""
    return (tuple(map(float, camera.position)), tuple(map(float, camera.focal_point)),
            tuple(map(float, camera.view_up)), float(camera.view_angle), bool(camera.parallel_projection),
            float(camera.parallel_scale), tuple(size), tuple(background))


class RendererContent(ViewContent):
    """One of our software renderers, run through its VTK filter (jitter passes accumulated while idle)."""

    uses_frames = True
    #: The picture is the frame alone (shown as the renderer's background, nothing drawn by VTK), so the command
    #: line takes it without an OpenGL context (:class:`app.pipeline.offscreen.FrameScene`).
    picture_is_frame = True
    filter = None

    def __init__(self, mode, options) -> None:
        super().__init__(mode, options)
        self._sum: np.ndarray | None = None  # running sum of the passes shown for ``_key``
        self._key: tuple | None = None
        self._passes_done = 0

    @property
    def passes(self) -> int:
        return int(self.options.get("passes") or 1) if self.options.get("jitter", False) else 1

    def _restart(self) -> None:
        self._sum, self._key, self._passes_done = None, None, 0

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None):
        return self.mode.make_filter(self.options, inputs)

    def install(self, renderer, inputs: ViewInputs, prepared) -> None:
        self.filter = prepared
        self._inputs = inputs
        self._restart()

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if self.filter is None:
            return IGNORE
        if change in ("transfer_function", "sample_distance"):
            self._restart()
            self.mode.configure_filter(self.filter, self.options, inputs)
            return REFRAME
        if change == "background":
            self._restart()
            return REFRAME
        if change == "selection":
            # Per-sample tools: the filter keeps its set-up, the next frame is cut (no data rewrite).
            self._restart()
            self.filter.SetTools(inputs.tool_set())
            return REFRAME
        return IGNORE

    def frame_work(self, renderer, camera: Camera, size: tuple[int, int]):
        algorithm, inputs = self.filter, self._inputs
        local = frame_camera(self.mode, camera, inputs)
        background = tuple(inputs.background)
        key = _frame_key(local, size, background)
        passes = self.passes
        if key == self._key and 0 < self._passes_done < passes:
            pass_index, previous = self._passes_done, self._sum  # refine the frame on show
        else:
            pass_index, previous = 0, None

        def work(progress=None) -> Frame:
            frame = filter_frame(algorithm, local, size, background, progress, pass_index=pass_index)
            # The running sum is kept only when more passes will follow.
            total = None if passes == 1 else (frame.image.astype(np.float64) if previous is None
                                              else previous + frame.image)
            if pass_index > 0:
                frame.image = np.clip(np.rint(total / (pass_index + 1)), 0, 255).astype(np.uint8)
            frame.stats["passes"] = pass_index + 1
            frame.stats["_accumulation"] = (key, pass_index + 1, total)
            return frame

        return work

    def refining(self) -> bool:
        """True while the frame on show is a jitter pass short of ``passes`` (the pipeline then asks for the next
        one, for the same camera and size, while the camera rests)."""
        return self.filter is not None and 0 < self._passes_done < self.passes

    def show_frame(self, renderer, frame: Frame) -> None:
        self._key, self._passes_done, self._sum = frame.stats.pop("_accumulation", (None, 0, None))
        if isinstance(renderer, FrameRenderer):  # headless: the frame is the picture, kept as it is
            renderer.show_frame(frame.image)
        else:
            super().show_frame(renderer, frame)
        self.stats = dict(frame.stats)

    def status(self) -> str:
        return format_frame_stats(self.stats)


class SliceStackContent(ViewContent):
    """Texture slicing composited by OpenGL: the slices are rebuilt for each camera and blended by VTK."""

    uses_frames = True
    stack = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None):
        return self.mode.make_slicer(self.options, inputs)

    def install(self, renderer, inputs: ViewInputs, prepared) -> None:
        from algorithms.rendering.texture_slicing import SliceStackProp

        self._inputs = inputs
        self.stack = SliceStackProp(prepared, user_matrix=inputs.item.local_to_world)
        self.stack.attach(renderer)
        self.props = [self.stack.prop]

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if change == "transfer_function":
            return REBUILD  # new textures for every slice
        return REFRAME if change in ("background", "selection") else IGNORE

    def frame_work(self, renderer, camera: Camera, size: tuple[int, int]):
        stack, local = self.stack, camera_in_frame(camera, self._inputs.item.local_to_world)
        tools = self._inputs.tool_set()

        def work(progress=None) -> Frame:
            start = time.perf_counter()
            parts, stats = stack.compute(local, *size, tools=tools, progress=progress)
            return Frame(None, {**stats, "parts": parts}, time.perf_counter() - start, pixels=size)

        return work

    def show_frame(self, renderer, frame: Frame) -> None:
        self.stack.show(frame.stats.pop("parts"))
        self.stats = dict(frame.stats)

    def status(self) -> str:
        return format_frame_stats(self.stats)

