"""Our software volume renderers as modes, each run through its VTK filter (image in, RGBA frame out):

- ``raymarch``: ray marching with Beer-Lambert absorption, Blinn-Phong or single scattering (sources 001, 002);
- ``slicing``, ``slicing-axis``: view-aligned and axis-aligned texture slicing (sources 001, 002), composited in
  float, in 8 bits, or by OpenGL;
- ``shear-warp``: Lacroute's shear-warp factorisation with run-length encoding (source 004), parallel or perspective
  (Lacroute's perspective factorisation), anisotropic volumes resampled to their smallest spacing by default.

Every renderer uses the view's transfer function and its shading material, so one preset means one picture, and
jitters its samples per pixel (``jitter``, on by default: no wood-grain rings; the same camera and size always give
the same frame); ``passes`` > 1 averages that many jitter passes once the camera rests (the window shows each pass
as it comes, the command line writes the last).

In a view (:class:`RendererContent`): the item's image -> the mode's renderer filter -> one RGBA frame per camera,
shown as the view's background (so the camera, its linking and the overlays stay VTK's).

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
from dataclasses import dataclass
from importlib import import_module
from typing import Any, Callable, Mapping

import numpy as np

from algorithms.common.camera import Camera

from ..pipeline.cameras import camera_in_frame
from ..pipeline.content import IGNORE, REBUILD, REFRAME, Frame, ViewContent, ViewInputs
from ..pipeline.frames import filter_frame, frame_camera
from ..pipeline.offscreen import FrameRenderer
from . import register_mode
from .base import Capabilities, Mode, Option


@dataclass(frozen=True)
class RendererMode(Mode):
    """One of our software renderers. ``filter_class`` is ``"module:Class"`` of its RendererFilter;
    ``configure(filter, options, inputs)`` applies the mode's options and the view's material to it."""

    filter_class: str = ""
    configure: Callable[..., None] | None = None

    def create_content(self, options: Mapping[str, Any]) -> ViewContent:
        return RendererContent(self, options)

    def make_filter(self, options: Mapping[str, Any], inputs: ViewInputs):
        """A configured filter on the item's shared image (set-up happens on its first update)."""
        module, name = self.filter_class.split(":")
        algorithm = getattr(import_module(module), name)()
        algorithm.SetInputDataObject(inputs.item.vtk_image())
        self.configure_filter(algorithm, options, inputs)
        return algorithm

    def configure_filter(self, algorithm, options: Mapping[str, Any], inputs: ViewInputs) -> None:
        """Apply the transfer function (as a table over the volume's value range) and the mode's options."""
        volume = inputs.volume
        algorithm.SetTransferTable(inputs.transfer_function.to_table(volume.value_range))
        if "jitter" in options:
            algorithm.SetJitter(bool(options["jitter"]))
        algorithm.SetTools(inputs.tool_set())
        if self.configure is not None:
            self.configure(algorithm, options, inputs)


#: Frame statistics shown in the view's header, in this order, and how.
_SHOWN_STATS = {
    "samples_per_ray": lambda v: f"{v:.1f} samples per ray",
    "early_terminated": lambda v: f"{100 * v:.0f} % of rays terminated early",
    "slices": lambda v: f"slices {v:.3g}",
    "voxels_composited": lambda v: f"voxels composited {v:.3g}",
    "passes": lambda v: f"{v:.0f} passes",
}


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
        if change == "cutaways":
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
        return REFRAME if change in ("background", "cutaways") else IGNORE

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


def _material(algorithm, inputs: ViewInputs) -> None:
    shading = inputs.transfer_function.shading
    algorithm.SetMaterial(shading.ambient, shading.diffuse, shading.specular, shading.specular_power)


def _configure_raymarch(algorithm, options, inputs: ViewInputs) -> None:
    from algorithms.rendering.raymarch import step_for_samples

    volume = inputs.volume
    if options["samples"]:
        distance = step_for_samples(volume.array.shape, volume.spacing, options["samples"])
    else:
        distance = inputs.effective_sample_distance()
    lighting = options["lighting"] or ("phong" if inputs.transfer_function.shading.enabled else "emission")
    algorithm.SetLighting(lighting)
    algorithm.SetSampleDistance(distance)
    algorithm.SetLightSamples(options["light_samples"])
    _material(algorithm, inputs)


def _configure_slicing(algorithm, options, inputs: ViewInputs) -> None:
    algorithm.SetPrecision("uint8" if options["compositing"] == "uint8" else "float")
    algorithm.SetShading(inputs.transfer_function.shading.enabled)
    _material(algorithm, inputs)
    if "slices" in options:
        algorithm.SetNumberOfSlices(options["slices"] or 0)
        algorithm.SetSliceDistance(options["slice_distance"])


def _configure_shear_warp(algorithm, options, inputs: ViewInputs) -> None:
    algorithm.SetResampleSpacing(options["resample_spacing"] or "auto")
    algorithm.SetShading(inputs.transfer_function.shading.enabled)
    _material(algorithm, inputs)


@dataclass(frozen=True)
class SlicingMode(RendererMode):
    """Texture slicing: composited by our float (or 8-bit) reference path, or drawn by OpenGL (``compositing=gl``)."""

    slicing: str = "view"

    def create_content(self, options: Mapping[str, Any]) -> ViewContent:
        return SliceStackContent(self, options) if options["compositing"] == "gl" else RendererContent(self, options)

    def check_options(self, options: Mapping[str, Any]) -> None:
        if options.get("slices") and options.get("slice_distance"):
            raise ValueError("give either a number of slices (--slices) or a slice distance (--slice-distance), "
                             "not both")

    def configure_filter(self, algorithm, options: Mapping[str, Any], inputs: ViewInputs) -> None:
        algorithm.SetMode(self.slicing)
        super().configure_filter(algorithm, options, inputs)

    def make_slicer(self, options: Mapping[str, Any], inputs: ViewInputs):
        """The slices and textures for OpenGL compositing (the framebuffer blends them)."""
        from algorithms.rendering.texture_slicing import SlicingRenderer

        volume = inputs.volume
        extra = {}
        if options.get("slices"):
            extra["slices"] = options["slices"]
        elif options.get("slice_distance"):
            extra["slice_distance"] = options["slice_distance"]
        shading = inputs.transfer_function.shading
        material = dict(ambient=shading.ambient, diffuse=shading.diffuse, specular=shading.specular,
                        specular_power=shading.specular_power)
        return SlicingRenderer(volume.array, volume.spacing, inputs.transfer_function.to_table(volume.value_range),
                               mode=self.slicing, precision="float", shading=shading.enabled,
                               jitter=bool(options.get("jitter", False)), **material, **extra)


COMPOSITING = Option("compositing", "str", "float", "texture slicing: accumulate in float, in 8 bits as a "
                     "framebuffer does, or draw the slices with OpenGL", choices=("float", "uint8", "gl"))
JITTER = Option("jitter", "bool", True, "offset each pixel's samples along its ray by a fixed interleaved pattern "
                "(no wood-grain rings; the same camera and size give the same frame; texture slicing: float and "
                "8-bit compositing)")
SHEAR_WARP_JITTER = Option(
    "jitter", "bool", False, "shear-warp: sample each ray between its crossings of two slices at the pixel's jitter, "
    "classifying the interpolated scalar there (no wood-grain rings, closer to vtk-gpu, about 1.7x the frame time; "
    "off by default: cut-away tools apply to the source's unjittered parallel path only)")
PASSES = Option("passes", "int", 1, "jitter passes averaged into a still frame once the camera rests (1: none)",
                minimum=1, maximum=256)
VOLUME_RENDERING = dict(group="Volume rendering", origin="ours", input="volume", output="image")

register_mode(RendererMode(
    "raymarch", "Ray marching", "Our ray marcher: Beer-Lambert absorption, Blinn-Phong or single scattering, early "
    "termination, empty-space skipping (sources 001, 002)", **VOLUME_RENDERING,
    filter_class="algorithms.rendering.raymarch:RaymarchFilter", configure=_configure_raymarch,
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_cutaways=True),
    options=(
        Option("lighting", "str", None, "ray marching: emission-absorption only, Blinn-Phong from gradients, or "
               "single scattering towards a light (default: the preset's shading)",
               choices=("emission", "phong", "scatter")),
        Option("samples", "int", None, "ray marching: samples across the volume's diagonal, instead of the sample "
               "distance (default: half the smallest voxel spacing apart)", minimum=2, maximum=100_000),
        Option("light_samples", "int", 8, "ray marching with scattering: samples towards the light per view sample "
               "(source 001 used 8)", minimum=1, maximum=1000),
        JITTER, PASSES,
    ),
))
register_mode(SlicingMode(
    "slicing", "Texture slicing", "View-aligned slices blended back to front (float compositing; compositing=gl "
    "draws them with OpenGL)", **VOLUME_RENDERING,
    filter_class="algorithms.rendering.texture_slicing:TextureSlicingFilter", configure=_configure_slicing,
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_cutaways=True), slicing="view",
    options=(
        Option("slices", "int", None, "texture slicing: number of view-aligned slices (default: one per smallest "
               "voxel spacing along the view)", minimum=2, maximum=100_000),
        Option("slice_distance", "float", None, "texture slicing: distance between slices (instead of a count)",
               unit="mm", minimum=1e-3),
        COMPOSITING, JITTER, PASSES,
    ),
))
register_mode(SlicingMode(
    "slicing-axis", "Axis-aligned slicing", "Three stacks of axis-aligned slices, the one most perpendicular to the "
    "view drawn back to front (source 002)", **VOLUME_RENDERING,
    filter_class="algorithms.rendering.texture_slicing:TextureSlicingFilter", configure=_configure_slicing,
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_cutaways=True), slicing="axis",
    options=(COMPOSITING,),
))
register_mode(RendererMode(
    "shear-warp", "Shear-warp", "Lacroute's shear-warp factorisation with run-length encoded volume and image, early "
    "termination (source 004; parallel, or perspective after Lacroute's perspective factorisation)",
    **VOLUME_RENDERING,
    filter_class="algorithms.rendering.shear_warp:ShearWarpFilter", configure=_configure_shear_warp,
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_cutaways=True),
    options=(
        Option("resample_spacing", "float", None, "shear-warp: render a grid of about this spacing (source 004's "
               "remedy for anisotropic voxels; default: anisotropic volumes at their smallest spacing, isotropic "
               "ones on their own grid)", unit="mm", minimum=1e-3),
        SHEAR_WARP_JITTER, PASSES,
    ),
))
