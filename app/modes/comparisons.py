"""Comparison modes: one of our methods against VTK's in the same view.

- ``marching-cubes-vs-flying-edges``: our surface coloured by its distance (mm) to flying edges' surface;
- ``raymarch-vs-vtk-gpu``, ``slicing-vs-vtk-gpu``, ``shear-warp-vs-vtk-gpu``: the heat map of the difference
  between our frame and VTK's GPU ray caster's at the same camera, with PSNR, RMSE and SSIM.

A comparison takes the options of the mode under test, so every setting of ours can be compared.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from ..pipeline.comparisons import ImageDifferenceContent, SurfaceDistanceContent
from ..pipeline.content import ViewContent
from . import get_mode, register_mode, renderers, surfaces, volume_mappers  # noqa: F401 - registered first
from .base import Mode, Option


@dataclass(frozen=True)
class ComparisonMode(Mode):
    """``test`` against ``reference`` (mode names): surfaces by distance, renderings by image difference."""

    test: str = ""
    reference: str = ""

    def create_content(self, options: Mapping[str, Any]) -> ViewContent:
        if get_mode(self.test).output == "surface":
            return SurfaceDistanceContent(self, options)
        if options.get("compositing") == "gl":
            raise ValueError("a comparison composites our slices in float; OpenGL compositing cannot be compared")
        return ImageDifferenceContent(self, options)

    def check_options(self, options: Mapping[str, Any]) -> None:
        get_mode(self.test).check_options(options)


#: The legends' scale (see :mod:`app.pipeline.comparisons`): a distance in mm for surfaces, a difference in
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
        output="comparison", options=(*tested.options, legend), capabilities=tested.capabilities, test=test,
        reference=reference,
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
