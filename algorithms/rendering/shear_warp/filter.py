"""The VTK filter of the shear-warp renderer: ``vtkImageData`` volume in, RGBA ``vtkImageData`` frame out."""

from __future__ import annotations

from ...common.render_filter import RendererFilter
from ...common.validation import validated_distance
from .renderer import ShearWarpRenderer


class ShearWarpFilter(RendererFilter):
    """VTK filter around :class:`ShearWarpRenderer`: ``vtkImageData`` (point scalars) in, RGBA image out.

    See :class:`algorithms.common.render_filter.RendererFilter` for the input, output and camera conventions (the
    camera must be parallel). Shading and early termination are set-up options: a change rebuilds the
    classification and encodings; a camera change only renders again.

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    >>> f = ShearWarpFilter()
    >>> f.SetInputDataObject(image_from_array(volume, spacing, origin))
    >>> f.SetTransferTable(table)
    >>> f.SetCamera(camera)          # parallel, in the image's frame
    >>> f.SetImageSize(512, 512)
    >>> rgba_image = run_algorithm(f)
    """

    label = "ShearWarpFilter"

    def __init__(self) -> None:
        super().__init__()
        self._shading = False
        self._early_termination: float | None = 0.99
        self._resample_spacing: float | None = None

    def SetShading(self, shading: bool) -> None:  # noqa: N802 - VTK naming
        self._set("_shading", bool(shading))

    def SetEarlyTermination(self, threshold: float | None) -> None:  # noqa: N802
        if threshold is not None and not 0.0 < threshold <= 1.0:
            raise ValueError(f"early_termination must lie in (0, 1] or be None, got {threshold}")
        self._set("_early_termination", threshold)

    def SetResampleSpacing(self, spacing: float | None) -> None:  # noqa: N802
        """Resample the volume to about this spacing (mm) before encoding; None keeps the volume's own grid."""
        if spacing is not None:
            spacing = validated_distance(spacing, "resample_spacing")
        self._set("_resample_spacing", spacing)

    def GetResampleSpacing(self) -> float | None:  # noqa: N802
        return self._resample_spacing

    def _setup_key(self) -> tuple:
        return (self._shading, self._early_termination, self._resample_spacing, self._material)

    def _create_renderer(self, array, spacing, table, progress) -> ShearWarpRenderer:
        return ShearWarpRenderer(array, spacing, table, shading=self._shading, resample_spacing=self._resample_spacing,
                                 early_termination=self._early_termination, progress=progress,
                                 **self._material_keywords())
