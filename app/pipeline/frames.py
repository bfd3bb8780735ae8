"""Frames of our software renderers: a renderer filter (a :class:`algorithms.common.render_filter.RendererFilter`)
run for one camera, size and jitter pass, and its premultiplied RGBA image put over the view's background. The
renderer modes (:mod:`app.modes.renderers`) and the image comparisons (:mod:`app.modes.comparisons`) make their
pictures with these.
"""

from __future__ import annotations

import time

import numpy as np
from vtkmodules.util import numpy_support

from algorithms.common.camera import Camera
from algorithms.common.vtk_bridge import run_algorithm

from .cameras import camera_in_frame
from .content import Frame, ViewInputs


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
