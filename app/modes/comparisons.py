"""Comparison modes: one of our methods against VTK's in the same view.

- ``marching-cubes-vs-flying-edges``: our surface coloured by its distance (mm) to flying edges' surface;
- ``raymarch-vs-vtk-gpu``, ``slicing-vs-vtk-gpu``, ``shear-warp-vs-vtk-gpu``: the heat map of the difference
  between our frame and VTK's GPU ray caster's at the same camera, with PSNR, RMSE and SSIM.

A comparison holds the two modes it compares (objects, not names) and takes the options of the mode under test, so
every setting of ours can be compared. Its view content:

- :class:`SurfaceDistanceContent`: the test mode's surface coloured by each vertex's distance (mm) to the reference
  mode's surface, with the Hausdorff distance, the mean symmetric distance and the 95th percentile.
- :class:`ImageDifferenceContent`: our renderer against a VTK volume mapper at the same camera and size, shown as a
  heat map of the difference with the foreground PSNR, RMSE and SSIM. VTK's picture is rendered on the owner thread
  (OpenGL) in an off-screen scene; ours and the difference off it.

Legends have a fixed meaning: their scale comes from a tolerance the user sets (the comparison modes' ``tolerance``
option in mm, default a tenth of the smallest voxel spacing; ``difference_tolerance`` in fractions of full scale,
default 0.05), never from the data's extremes. The distance view is blue at 0, white at the tolerance and red from
twice it; the heat map runs from black at 0 to pale yellow at twice the tolerance. So rounding noise (1e-5 mm between
marching cubes and flying edges) shows as the calm colour it is, and two views with the same tolerance can be read
side by side. Both have a colour bar with labels in mm or in fractions of full scale.

Tests, benchmarks and the window share :func:`surface_distance` and :func:`image_difference`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
from vtkmodules.util import numpy_support

from algorithms.common.camera import Camera
from algorithms.common.progress import ProgressCallback, scaled

from ..pipeline.content import IGNORE, REBUILD, Frame, ViewContent, ViewInputs
from ..pipeline.frames import filter_frame, frame_camera
from ..pipeline.lit_surfaces import LitContent, SurfaceResult
from ..pipeline.offscreen import OffscreenScene
from ..pipeline.props import difference_bar, distance_actor, volume_prop
from . import get_mode, register_mode, renderers, surfaces, volume_mappers  # noqa: F401 - registered first
from .base import Mode, Option

DISTANCE_ARRAY = "distance_mm"
#: The options of a comparison that set its legend, not the mode under test.
LEGEND_OPTIONS = ("tolerance", "difference_tolerance")
#: Default scale of the image-difference legend (fraction of full scale, about 13 of 255 grey levels).
DIFFERENCE_TOLERANCE = 0.05


def tested_options(options) -> dict[str, Any]:
    """A comparison's options without the legend's: what the mode under test takes."""
    return {k: v for k, v in dict(options or {}).items() if k not in LEGEND_OPTIONS}


def distance_tolerance(options, volume) -> float:
    """The distance legend's tolerance (mm): the option, else a tenth of the smallest voxel spacing."""
    value = (options or {}).get("tolerance")
    return float(value) if value is not None else 0.1 * float(min(volume.spacing))


def surface_distance(item, test: "Mode", reference: "Mode", iso: float, *, options=None,
                     progress: ProgressCallback = None) -> SurfaceResult:
    """The ``test`` surface mode's surface with a point array ``distance_mm``: each vertex's distance to
    ``reference``'s.

    ``stats`` carries the test surface's counts plus ``hausdorff_mm`` (largest vertex distance either way),
    ``mean_mm`` (mean symmetric surface distance) and ``p95_mm`` (95th percentile of the test-to-reference
    distances).
    """
    from algorithms.compare.measures import distance_to_surface
    from algorithms.compare.triangles import surface_arrays

    ours = test.extract(item, iso, options=tested_options(options), progress=scaled(progress, 0.0, 0.3))
    theirs = reference.extract(item, iso, progress=scaled(progress, 0.3, 0.5))
    points_a, triangles_a = surface_arrays(ours.polydata)
    points_b, triangles_b = surface_arrays(theirs.polydata)
    if len(triangles_a) == 0 or len(triangles_b) == 0:
        units = getattr(getattr(item, "volume", item), "units_label", "")
        raise ValueError(f"no surface at {iso:g} {units}: nothing to compare")
    a_to_b = distance_to_surface(points_a, (points_b, triangles_b), progress=scaled(progress, 0.5, 0.8))
    b_to_a = distance_to_surface(points_b[np.unique(triangles_b)], (points_a, triangles_a),
                                 progress=scaled(progress, 0.8, 1.0))
    used = np.unique(triangles_a)
    array = numpy_support.numpy_to_vtk(a_to_b.astype(np.float32), deep=True)
    array.SetName(DISTANCE_ARRAY)
    polydata = ours.polydata.NewInstance()
    polydata.ShallowCopy(ours.polydata)
    polydata.GetPointData().AddArray(array)
    stats = dict(ours.stats)
    stats.update({
        "hausdorff_mm": float(max(a_to_b[used].max(), b_to_a.max())),
        "mean_mm": float((a_to_b[used].sum() + b_to_a.sum()) / (used.size + b_to_a.size)),
        "p95_mm": float(np.percentile(a_to_b[used], 95)),
        "reference_triangles": theirs.stats["triangles"],
    })
    return SurfaceResult(polydata, stats)


@dataclass
class ImageDifference:
    """The heat map of |test - reference| and the comparison numbers (PSNR over the foreground, RMSE, SSIM)."""

    heatmap: np.ndarray  # (h, w, 3) uint8
    numbers: dict[str, Any] = field(default_factory=dict)


def image_difference(test: np.ndarray, reference: np.ndarray, *, background=(0.0, 0.0, 0.0),
                     tolerance: float = DIFFERENCE_TOLERANCE) -> ImageDifference:
    """Compare two renderings of the same view (``(h, w, 3)`` uint8 or float in [0, 1]); the heat map spans 0 to
    twice ``tolerance`` (fractions of full scale), whatever the differences are."""
    from algorithms.compare.image_metrics import compare_images, difference_heatmap

    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"the difference tolerance must be a positive fraction of full scale, got {tolerance}")
    comparison = compare_images(test, reference, background=background)
    numbers = {**comparison.as_dict(), "legend_top": 2.0 * tolerance}
    return ImageDifference(difference_heatmap(test, reference, vmax=2.0 * tolerance), numbers)


class SurfaceDistanceContent(LitContent):
    """The test mode's surface coloured by its distance to the reference mode's surface."""

    result: SurfaceResult | None = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None) -> SurfaceResult:
        return surface_distance(inputs.item, self.mode.test, self.mode.reference, inputs.iso, options=self.options,
                                progress=progress)

    def install(self, renderer, inputs: ViewInputs, prepared: SurfaceResult) -> None:
        self.result = prepared
        tolerance = distance_tolerance(self.options, inputs.volume)
        self.stats = {**prepared.stats, "tolerance_mm": tolerance}
        actor, bar = distance_actor(prepared.polydata, inputs.item.local_to_world, DISTANCE_ARRAY,
                                    tolerance_mm=tolerance)
        self.scalar_bar = bar
        self._replace_props(renderer, [actor, bar], detail_mm=max(inputs.volume.spacing))

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        return REBUILD if change == "iso" else IGNORE

    def status(self) -> str:
        s = self.stats
        if not s:
            return ""
        return (f"distance to {self.mode.reference.label}: Hausdorff {s['hausdorff_mm']:.3g} mm, "
                f"mean {s['mean_mm']:.3g} mm, 95 % {s['p95_mm']:.3g} mm (white: {s['tolerance_mm']:.3g} mm)")


class ImageDifferenceContent(ViewContent):
    """Our renderer's frame against a VTK volume mapper's frame at the same camera: the heat map of their
    difference and its numbers."""

    uses_frames = True
    filter = None
    reference = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None):
        return self.mode.test.make_filter(tested_options(self.options), inputs)

    def install(self, renderer, inputs: ViewInputs, prepared) -> None:
        self.close()
        self.filter, self._inputs = prepared, inputs
        self._tolerance = float(self.options.get("difference_tolerance") or DIFFERENCE_TOLERANCE)
        self._replace_props(renderer, [difference_bar(self._tolerance)])
        self.reference = OffscreenScene((64, 64), inputs.background)
        self.reference.add(volume_prop(inputs.volume, inputs.transfer_function,
                                       mapper=self.mode.reference.mapper,
                                       sample_distance=inputs.effective_sample_distance(),
                                       image=inputs.item.vtk_image()))

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if self.filter is None:
            return IGNORE
        if change in ("transfer_function", "sample_distance", "background"):
            return REBUILD
        return IGNORE

    def frame_work(self, renderer, camera: Camera, size: tuple[int, int]):
        inputs, algorithm = self._inputs, self.filter
        background = tuple(inputs.background)
        local = frame_camera(self.mode.test, camera, inputs)
        world = camera.as_parallel() if self.mode.test.capabilities.parallel_only else camera
        # VTK's picture now, on the owner thread (OpenGL); ours and the difference in the worker.
        self.reference.set_size(*size)
        self.reference.set_camera(world)
        self.reference.render()
        reference = self.reference.capture()

        def work(progress=None) -> Frame:
            ours = filter_frame(algorithm, local, size, background, progress)
            difference = image_difference(ours.image, reference, background=background, tolerance=self._tolerance)
            return Frame(difference.heatmap, {**difference.numbers, "seconds": ours.seconds}, ours.seconds)

        return work

    def show_frame(self, renderer, frame: Frame) -> None:
        super().show_frame(renderer, frame)
        self.stats = dict(frame.stats)

    def status(self) -> str:
        s = self.stats
        parts = []
        if "psnr_foreground" in s:
            parts.append(f"PSNR {s['psnr_foreground']:.1f} dB (foreground)")
        if "rmse" in s:
            parts.append(f"RMSE {s['rmse']:.4f}")
        if "ssim" in s:
            parts.append(f"SSIM {s['ssim']:.3f}")
        return ", ".join(parts)

    def close(self) -> None:
        if self.reference is not None:
            self.reference.close()
            self.reference = None


@dataclass(frozen=True)
class ComparisonMode(Mode):
    """``test`` against ``reference`` (the modes themselves): surfaces by distance, renderings by image
    difference."""

    test: Mode | None = None
    reference: Mode | None = None

    def create_content(self, options: Mapping[str, Any]) -> ViewContent:
        if self.test.output == "surface":
            return SurfaceDistanceContent(self, options)
        if options.get("compositing") == "gl":
            raise ValueError("a comparison composites our slices in float; OpenGL compositing cannot be compared")
        return ImageDifferenceContent(self, options)

    def check_options(self, options: Mapping[str, Any]) -> None:
        self.test.check_options(options)


#: The legends' scale (see the module notes): a distance in mm for surfaces, a difference in
#: fractions of full scale for images, shown at the middle of the colour bar.
SURFACE_TOLERANCE = Option("tolerance", "float", None, "legend: the distance shown white, in the middle of the colour "
                           "bar, which spans twice it (default: a tenth of the smallest voxel spacing)", unit="mm",
                           minimum=1e-9, maximum=1e6)
IMAGE_TOLERANCE = Option("difference_tolerance", "float", 0.05, "legend: the difference (fraction of full scale, "
                         "0-1) shown in the middle of the colour bar, which spans twice it", minimum=1e-4, maximum=0.5)


def _comparison(test: str, reference: str, label: str, description: str) -> ComparisonMode:
    tested = get_mode(test)
    legend = SURFACE_TOLERANCE if tested.output == "surface" else IMAGE_TOLERANCE
    return ComparisonMode(
        f"{test}-vs-{reference}", label, description, group="Comparisons", origin="ours", input=tested.input,
        output="comparison", options=(*tested.options, legend), capabilities=tested.capabilities, test=tested,
        reference=get_mode(reference),
    )


register_mode(_comparison(
    "marching-cubes", "flying-edges", "Marching cubes against flying edges (distance, mm)",
    "Our marching-cubes surface coloured by its distance (mm) to VTK's flying-edges surface",
))
for _test, _name in (("raymarch", "Ray marching"), ("slicing", "Texture slicing"), ("shear-warp", "Shear-warp")):
    register_mode(_comparison(
        _test, "vtk-gpu", f"{_name} against GPU ray casting (difference)",
        f"Heat map of the difference between our {_name.lower()} and VTK's GPU ray caster at the same camera, "
        "with PSNR, RMSE and SSIM",
    ))
