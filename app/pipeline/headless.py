"""One off-screen render of any mode, with frame timing: the logic behind ``voxelscope render``.

It builds the same :class:`~app.pipeline.view.ViewPipeline` a window view builds, on an off-screen scene, with an
:class:`~app.pipeline.jobs.ImmediateRunner`, so a PNG shows exactly what a view shows. The JSON report carries the
same fields for every mode: the set-up seconds (surface extraction, mapper set-up, classification and encodings,
first frame) apart from the per-frame seconds of a turning camera.

Modes whose picture is our software renderer's frame alone (``picture_is_frame`` of their content: ray marching,
shear-warp, slicing composited by us) render into a :class:`~app.pipeline.offscreen.FrameScene`: no render window,
no OpenGL context, no VTK rendering module, the frame taken as it is - the same pixels an OpenGL render of the frame
as background reads back, without the ~80 MiB of a Mesa context and the ~12 MiB of ``vtkRenderingCore`` (issue
20). Every other mode renders in an :class:`~app.pipeline.offscreen.OffscreenScene`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np

from algorithms.common.camera import Camera
from algorithms.common.progress import ProgressCallback

from ..transfer import transfer_function_for
from ..volume import default_iso
from .cameras import default_camera, turning_cameras
from .content import ViewInputs
from .jobs import ImmediateRunner
from .offscreen import DEFAULT_SIZE, FrameScene, OffscreenScene
from .timing import FrameTimes
from .view import ViewPipeline


@dataclass
class RenderSettings:
    """What to render and how; the defaults are the command line's.

    ``mode`` is a :class:`~app.modes.base.Mode` (``app.modes.get_mode`` finds one by name); ``options`` are the
    mode's own (see ``voxelscope modes``); ``sample_distance`` (mm) applies to ray casting (ours and VTK's); ``iso``
    (the volume's units) to surfaces.
    """

    mode: Any
    options: dict[str, Any] = field(default_factory=dict)
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
    camera: Camera | None = None  # a given camera (world, LPS) instead of the view/azimuth/elevation default
    tools: tuple = ()  # cut-away tools (algorithms.fields.cutaway_tools.Tool, LPS mm)
    cut_evaluation: str = "binary"


@dataclass
class RenderReport:
    """The captured picture, the pipeline's own last frame for software renderers (what a window view shows as its
    background), and the JSON report."""

    image: np.ndarray  # (h, w, 3) uint8, row 0 at the top
    info: dict[str, Any]
    frame: np.ndarray | None = None


def view_inputs(item, *, iso=None, preset=None, shading=None, sample_distance=None, background=(0.0, 0.0, 0.0),
                interactive=False, uses_iso: bool = True) -> ViewInputs:
    """The inputs a view starts from for an item: its default isovalue and transfer function unless given.

    ``uses_iso=False`` (a render whose content never reads the isovalue: our software renderers) leaves an isovalue
    that is not given at 0 instead of working out the default (which imports the meshing code and, for volumes not
    in HU, takes a percentile pass over the data).
    """
    volume = getattr(item, "volume", None)
    function = transfer_function_for(volume, preset, shading=shading) if volume is not None else None
    if iso is None:
        iso = getattr(item, "iso", None) if volume is not None and hasattr(item, "role") else None
        if iso is None and volume is not None and uses_iso:
            iso = default_iso(volume)
    return ViewInputs(item, float(iso if iso is not None else 0.0), function, sample_distance, tuple(background),
                      interactive)


def render_item(item, settings: RenderSettings, *, progress: ProgressCallback = None) -> RenderReport:
    """Render a scene item off-screen as ``settings`` say; time the set-up and, with ``frames``, a turning camera."""
    mode = settings.mode
    width, height = (int(v) for v in settings.size)
    if width < 8 or height < 8 or width > 8192 or height > 8192:
        raise ValueError(f"image size must be between 8 and 8192 pixels per side, got {width} x {height}")
    if settings.frames < 0:
        raise ValueError(f"frames must be 0 or more, got {settings.frames}")
    if mode.capabilities.parallel_only and not settings.parallel and settings.camera is None:
        raise ValueError(f"mode {mode.name!r} renders with parallel projection only; add --parallel")
    options = mode.resolve_options(settings.options)
    frame_only = picture_is_frame(mode, options)
    inputs = view_inputs(item, iso=settings.iso, preset=settings.preset, shading=settings.shading,
                         sample_distance=settings.sample_distance, background=settings.background,
                         uses_iso=not frame_only or mode.capabilities.uses_iso)
    if settings.tools:
        if not mode.capabilities.accepts_cutaways:
            raise ValueError(f"mode {mode.name!r} does not honour cut-away tools (--cut); see 'voxelscope modes' "
                             "for those that do")
        if getattr(item, "volume", None) is None:
            raise ValueError(f"{item.name} is a {item.kind}; cut-away tools (--cut) apply to volumes")
        inputs = replace(inputs, tools=tuple(settings.tools), cut_evaluation=settings.cut_evaluation)
    camera = settings.camera or default_camera(item, view=settings.view, azimuth=settings.azimuth,
                                               elevation=settings.elevation, parallel=settings.parallel,
                                               aspect=width / height)
    info: dict[str, Any] = {
        "mode": mode.name,
        "output": mode.output,
        "item": item.name,
        "size": [width, height],
        "camera": {
            "position": [round(v, 4) for v in camera.position],
            "focal_point": [round(v, 4) for v in camera.focal_point],
            "view_up": [round(v, 6) for v in camera.view_up],
            "parallel": camera.parallel_projection,
            "coordinates": "LPS mm",
        },
        "options": {k: v for k, v in settings.options.items() if v is not None},
    }
    if inputs.transfer_function is not None:
        info["preset"] = inputs.transfer_function.name
        info["shading"] = inputs.transfer_function.shading.enabled
    if mode.capabilities.uses_iso:
        info.update({"iso": inputs.iso, "iso_units": inputs.volume.units_label})
    if mode.output in ("volume", "image", "comparison") and hasattr(item, "volume"):
        info["sample_distance_mm"] = inputs.effective_sample_distance()

    scene = (FrameScene if frame_only else OffscreenScene)((width, height), settings.background)
    pipeline = ViewPipeline(scene.renderer, ImmediateRunner(progress), lambda: (width, height))
    try:
        start = time.perf_counter()
        pipeline.set_camera(camera)
        pipeline.set_inputs(inputs)
        pipeline.set_mode(mode, options)
        scene.render()
        setup_seconds = time.perf_counter() - start
        image = scene.capture()
        content = pipeline.content
        frame = pipeline.last_frame.image if pipeline.last_frame is not None else None
        _report_content(info, mode, content)
        if settings.tools:
            info["cut"] = _cut_report(settings, pipeline, scene, content)
        if settings.frames:
            times = []
            cameras = turning_cameras(camera, settings.frames)
            for index, frame_camera in enumerate(cameras):
                tick = time.perf_counter()
                pipeline.set_camera(frame_camera)
                scene.render()
                times.append(time.perf_counter() - tick)
                if progress is not None:
                    progress((index + 1) / len(cameras))
            info.update(FrameTimes(setup_seconds, times).summary())
        else:
            info["setup_seconds"] = setup_seconds
    finally:
        pipeline.shutdown()
        scene.close()
    return RenderReport(image, info, frame)


def picture_is_frame(mode, options) -> bool:
    """Whether ``mode`` with ``options`` shows our software renderer's frame and nothing drawn by VTK (its content
    class says so with ``picture_is_frame``), so it renders without an OpenGL context."""
    return bool(getattr(type(mode.create_content(options)), "picture_is_frame", False))


def _cut_report(settings: RenderSettings, pipeline, scene, content) -> dict[str, Any]:
    """The tools used and the seconds the cut added: building the cut volume (surfaces) or the mapper's mask or
    masked copy (VTK's mappers), or, for our renderers (evaluated per sample), the frame with the tools minus a frame
    of the same camera without them (both rendered once more here, the cut one last, so the picture is unchanged)."""
    from ..cutaways import describe_tools

    report = describe_tools(settings.tools, settings.cut_evaluation)
    stats = content.stats if content is not None else {}
    if "cut_seconds" in stats:
        report["seconds"] = float(stats["cut_seconds"])
        report["how"] = stats.get("cut", "CSG difference written into a copy for extraction")
    elif content is not None and content.uses_frames and pipeline.last_frame is not None:
        # The first frame may have loaded the kernels: time an uncut frame and the cut frame again, in that order.
        tools = pipeline.inputs.tools
        pipeline.set_tools((), settings.cut_evaluation)
        scene.render()
        without = float(pipeline.last_frame.seconds)
        pipeline.set_tools(tools, settings.cut_evaluation)
        scene.render()
        with_tools = float(pipeline.last_frame.seconds)
        report.update(seconds=with_tools - without, frame_seconds=with_tools, uncut_frame_seconds=without,
                      how="per sample, no data rewrite")
    return report


def _report_content(info: dict[str, Any], mode, content) -> None:
    """The content's numbers under the keys ``render --json`` documents."""
    if content is None:
        return
    stats = {k: v for k, v in content.stats.items() if k != "parts"}
    if mode.output == "tetmesh":
        info["tetmesh"] = stats
    elif mode.output == "surface" or (mode.output == "comparison" and not content.uses_frames):
        info["surface"] = stats
    elif mode.output == "comparison":
        info["comparison"] = stats
    elif content.uses_frames:
        info["frame_stats"] = stats


def parse_background(values: Sequence[float]) -> tuple[float, float, float]:
    """Background colour from three numbers, either all in [0, 1] or 0-255 integers."""
    if len(values) != 3:
        raise ValueError(f"a background colour needs three values (R G B), got {len(values)}")
    if any(v < 0 for v in values) or any(v > 255 for v in values):
        raise ValueError(f"background values must lie in [0, 1] or [0, 255], got {list(values)}")
    scale = 255.0 if any(v > 1 for v in values) else 1.0
    return tuple(float(v) / scale for v in values)
