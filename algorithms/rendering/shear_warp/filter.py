"""The VTK filter of the shear-warp renderer: ``vtkImageData`` volume in, RGBA ``vtkImageData`` frame out."""

from __future__ import annotations

from ...common.render_filter import RendererFilter
from ...common.validation import validated_distance
from .renderer import ShearWarpRenderer


class ShearWarpFilter(RendererFilter):
    """VTK filter around :class:`ShearWarpRenderer`: ``vtkImageData`` (point scalars) in, RGBA image out.

    See :class:`algorithms.common.render_filter.RendererFilter` for the input, output and camera conventions (the
    camera may be parallel or perspective, outside the volume's box). Shading and early termination are set-up
    options: a change rebuilds the classification and encodings; a camera change only renders again.

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    >>> f = ShearWarpFilter()
    >>> f.SetInputDataObject(image_from_array(volume, spacing, origin))
    >>> f.SetTransferTable(table)
    >>> f.SetCamera(camera)          # in the image's frame
    >>> f.SetImageSize(512, 512)
    >>> rgba_image = run_algorithm(f)
    """

    label = "ShearWarpFilter"

    def __init__(self) -> None:
        super().__init__()
        self._shading = False
        self._early_termination: float | None = 0.99
        self._resample_spacing: float | str | None = "auto"

    def SetShading(self, shading: bool) -> None:  # noqa: N802 - VTK naming
        self._set("_shading", bool(shading))

    def SetEarlyTermination(self, threshold: float | None) -> None:  # noqa: N802
        if threshold is not None and not 0.0 < threshold <= 1.0:
            raise ValueError(f"early_termination must lie in (0, 1] or be None, got {threshold}")
        self._set("_early_termination", threshold)

    def SetResampleSpacing(self, spacing: float | str | None) -> None:  # noqa: N802
        """Render a grid of about this spacing (mm); ``"auto"`` (the default) resamples anisotropic volumes to their
        smallest spacing; None keeps the volume's own grid."""
        if spacing == "auto":
            pass
        elif spacing is not None:
            spacing = validated_distance(spacing, "resample_spacing")
        self._set("_resample_spacing", spacing)

    def GetResampleSpacing(self) -> float | None:  # noqa: N802
        return self._resample_spacing

    def _setup_key(self) -> tuple:
        return (self._shading, self._early_termination, self._resample_spacing, self._material)

    def _create_renderer(self, array, spacing, table, progress) -> ShearWarpRenderer:
        # Lazy copies: a frame needs only its principal axis's encoding (a third of the memory for a still image).
        return ShearWarpRenderer(array, spacing, table, shading=self._shading, resample_spacing=self._resample_spacing,
                                 early_termination=self._early_termination, jitter=self._jitter, lazy=True,
                                 progress=progress, **self._material_keywords())
