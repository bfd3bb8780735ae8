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
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import Any, Callable, Mapping

from ..pipeline.content import ViewContent, ViewInputs
from ..pipeline.images import RendererContent, SliceStackContent
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
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_selection=True),
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
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_selection=True), slicing="view",
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
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_selection=True), slicing="axis",
    options=(COMPOSITING,),
))
register_mode(RendererMode(
    "shear-warp", "Shear-warp", "Lacroute's shear-warp factorisation with run-length encoded volume and image, early "
    "termination (source 004; parallel, or perspective after Lacroute's perspective factorisation)",
    **VOLUME_RENDERING,
    filter_class="algorithms.rendering.shear_warp:ShearWarpFilter", configure=_configure_shear_warp,
    capabilities=Capabilities(uses_transfer_function=True, software=True, accepts_selection=True),
    options=(
        Option("resample_spacing", "float", None, "shear-warp: render a grid of about this spacing (source 004's "
               "remedy for anisotropic voxels; default: anisotropic volumes at their smallest spacing, isotropic "
               "ones on their own grid)", unit="mm", minimum=1e-3),
        SHEAR_WARP_JITTER, PASSES,
    ),
))
