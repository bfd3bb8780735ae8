"""The one view pipeline: what the command line and every window view use to show a scene item in a render mode.

- :class:`ViewPipeline` (``view.py``): one view's VTK pipeline, kept up to date as its inputs change; it takes
  :class:`app.modes.base.Mode` objects (the registry in :mod:`app.modes` finds them by name) and never imports the
  modes: each mode family (:mod:`app.modes.surfaces`, ``.renderers``, ``.volume_mappers``, ``.comparisons``,
  ``.tetrahedra``, ``.meshes``) holds its registration and its view content in one module;
- what contents share: ``content.py`` (the base and the immutable :class:`ViewInputs`), ``lit_surfaces.py`` (a
  surface result and the lighting of every surface), ``frames.py`` (a renderer filter's frame over a background);
- ``jobs.py``: where long work runs (the host's runner); ``cameras.py``: cameras in patient coordinates;
  ``props.py``: the VTK props every view uses; ``offscreen.py``: off-screen scenes and PNG files;
  ``headless.py``: ``voxelscope render``; ``timing.py``: frame-time statistics.
"""

from .cameras import STANDARD_VIEWS, camera_in_frame, default_camera, fit_camera, turning_cameras
from .content import Frame, ViewContent, ViewInputs
from .headless import RenderReport, RenderSettings, parse_background, render_item, view_inputs
from .jobs import ImmediateRunner, JobRunner
from .offscreen import OffscreenScene, read_png, write_png
from .timing import FrameTimes, Timing, paired_ratio, time_call, time_interleaved
from .view import ViewPipeline

__all__ = [
    "STANDARD_VIEWS", "camera_in_frame", "default_camera", "fit_camera", "turning_cameras", "Frame", "ViewContent",
    "ViewInputs", "RenderReport", "RenderSettings", "parse_background", "render_item", "view_inputs",
    "ImmediateRunner", "JobRunner", "OffscreenScene", "read_png", "write_png", "FrameTimes", "Timing", "time_call",
    "time_interleaved", "paired_ratio",
    "ViewPipeline",
]
