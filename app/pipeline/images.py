"""Our software renderers as view content: the item's image -> the mode's renderer filter -> one RGBA frame per
camera, shown as the view's background (so the camera, its linking and the overlays stay VTK's).

The filter (a :class:`algorithms.common.render_filter.RendererFilter`) keeps its set-up - classification,
encodings, gradients - between frames and rebuilds it only when its input, transfer table or a set-up option
changes; a frame costs one filter update. Frames are made off the owner thread (the filter is touched by one frame
job at a time) and composited over the view's background.

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

#: Frame statistics shown in the view's header, in this order, and how.
_SHOWN_STATS = {
    "samples_per_ray": lambda v: f"{v:.1f} samples per ray",
    "early_terminated": lambda v: f"{100 * v:.0f} % of rays terminated early",
    "slices": lambda v: f"slices {v:.3g}",
    "voxels_composited": lambda v: f"voxels composited {v:.3g}",
}


def frame_camera(mode, camera: Camera, inputs: ViewInputs) -> Camera:
    """The world camera as the mode's renderer needs it: in the item's volume frame, parallel if the mode
    renders in parallel only (a linked perspective view is then followed at its focal plane)."""
    if mode.capabilities.parallel_only:
        camera = camera.as_parallel()
    return camera_in_frame(camera, inputs.item.local_to_world)


def rgba_to_rgb(rgba: np.ndarray, background) -> np.ndarray:
    """An ``(h, w, 4)`` uint8 premultiplied image (row 0 at the top) over a background colour, as uint8 RGB."""
    colour = rgba[..., :3].astype(np.float32)
    alpha = rgba[..., 3:4].astype(np.float32) / 255.0
    back = np.asarray(background, dtype=np.float32).reshape(1, 1, 3) * 255.0
    return np.clip(np.rint(colour + (1.0 - alpha) * back), 0, 255).astype(np.uint8)


def filter_frame(algorithm, camera: Camera, size: tuple[int, int], background, progress=None) -> Frame:
    """Run a renderer filter for one camera (its input's frame) and size; the frame over ``background``."""
    from vtkmodules.util import numpy_support

    algorithm.SetCamera(camera)
    algorithm.SetImageSize(*size)
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


class RendererContent(ViewContent):
    """One of our software renderers, run through its VTK filter."""

    uses_frames = True
    filter = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None):
        return self.mode.make_filter(self.options, inputs)

    def install(self, renderer, inputs: ViewInputs, prepared) -> None:
        self.filter = prepared
        self._inputs = inputs

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if self.filter is None:
            return IGNORE
        if change in ("transfer_function", "sample_distance"):
            self.mode.configure_filter(self.filter, self.options, inputs)
            return REFRAME
        return REFRAME if change == "background" else IGNORE

    def frame_work(self, renderer, camera: Camera, size: tuple[int, int]):
        algorithm, inputs = self.filter, self._inputs
        local = frame_camera(self.mode, camera, inputs)
        background = tuple(inputs.background)

        def work(progress=None) -> Frame:
            return filter_frame(algorithm, local, size, background, progress)

        return work

    def show_frame(self, renderer, frame: Frame) -> None:
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
        return REFRAME if change == "background" else IGNORE

    def frame_work(self, renderer, camera: Camera, size: tuple[int, int]):
        stack, local = self.stack, camera_in_frame(camera, self._inputs.item.local_to_world)

        def work(progress=None) -> Frame:
            start = time.perf_counter()
            parts, stats = stack.compute(local, *size, progress=progress)
            return Frame(None, {**stats, "parts": parts}, time.perf_counter() - start, pixels=size)

        return work

    def show_frame(self, renderer, frame: Frame) -> None:
        self.stack.show(frame.stats.pop("parts"))
        self.stats = dict(frame.stats)

    def status(self) -> str:
        return format_frame_stats(self.stats)

