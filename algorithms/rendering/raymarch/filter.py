"""The VTK filter of the ray marcher: ``vtkImageData`` volume in, RGBA ``vtkImageData`` frame out."""

from __future__ import annotations

from ...common.render_filter import RendererFilter
from ...common.validation import validated_count, validated_distance
from .core import RaymarchRenderer, checked_lighting


class RaymarchFilter(RendererFilter):
    """VTK filter around :class:`RaymarchRenderer`: ``vtkImageData`` volume in, RGBA ``vtkImageData`` frame out.

    See :class:`algorithms.common.render_filter.RendererFilter` for the input, output and camera conventions;
    the lighting model and the sample distance are set-up options (a change rebuilds the renderer).

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    >>> f = RaymarchFilter()
    >>> f.SetInputDataObject(image_from_array(volume, spacing, origin))
    >>> f.SetTransferTable(table)
    >>> f.SetCamera(camera)
    >>> f.SetImageSize(256, 256)
    >>> rgba_image = run_algorithm(f)
    """

    label = "RaymarchFilter"

    def __init__(self) -> None:
        super().__init__()
        self._lighting = "emission"
        self._sample_distance: float | None = None
        self._light_samples = 8

    def SetLighting(self, lighting: str) -> None:  # noqa: N802 - VTK naming
        self._set("_lighting", checked_lighting(lighting))

    def GetLighting(self) -> str:  # noqa: N802
        return self._lighting

    def SetSampleDistance(self, sample_distance: float | None) -> None:  # noqa: N802
        """Distance between samples along a ray in mm; None for the default (half the smallest spacing)."""
        if sample_distance is not None:
            sample_distance = validated_distance(sample_distance, "sample_distance")
        self._set("_sample_distance", sample_distance)

    def GetSampleDistance(self) -> float | None:  # noqa: N802
        return self._sample_distance

    def SetLightSamples(self, count: int) -> None:  # noqa: N802
        """Samples towards the light per view sample (scatter lighting)."""
        self._set("_light_samples", validated_count(count, "light_samples"))

    def GetLightSamples(self) -> int:  # noqa: N802
        return self._light_samples

    def _setup_key(self) -> tuple:
        return (self._lighting, self._sample_distance, self._light_samples, self._material)

    def _create_renderer(self, array, spacing, table, progress) -> RaymarchRenderer:
        return RaymarchRenderer(array, spacing, table, sample_distance=self._sample_distance,
                                lighting=self._lighting, light_samples=self._light_samples, jitter=self._jitter,
                                progress=progress, **self._material_keywords())
