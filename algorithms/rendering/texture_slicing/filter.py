"""The VTK filter of texture slicing: ``vtkImageData`` volume in, RGBA ``vtkImageData`` frame out.

The frame is the float path's (:class:`~.renderer.SlicingRenderer`); whoever needs the slice polygons themselves
takes :func:`~.geometry.slices_to_polydata` of :func:`~.geometry.slice_polygons` or
:func:`~.geometry.axis_aligned_slices`.
"""

from __future__ import annotations

from ...common.render_filter import RendererFilter
from ...common.validation import validated_distance
from .renderer import SlicingRenderer, checked_mode, checked_precision


class TextureSlicingFilter(RendererFilter):
    """VTK filter around :class:`SlicingRenderer`: ``vtkImageData`` volume in, RGBA ``vtkImageData`` frame out.

    See :class:`algorithms.common.render_filter.RendererFilter` for the input, output and camera conventions
    (camera, image size and transfer table; errors as VTK error events, so
    :func:`~algorithms.common.vtk_bridge.run_algorithm` raises a ``VTKError``). The slicing options are set-up
    options (a change rebuilds the renderer; a camera change renders again):

    - ``SetMode("view" | "axis")``: view-aligned slices (default) or the axis-aligned stack through the voxel
      layers;
    - ``SetNumberOfSlices(n)``: a fixed number of view-aligned slices (0, the default: one per smallest spacing);
    - ``SetSliceDistance(mm)``: view-aligned slices at most this far apart (None, the default: the smallest
      spacing); giving both a number and a distance fails when the filter runs;
    - ``SetPrecision("float" | "uint8")``: float compositing, or rounding to 8 bits after every slice;
    - ``SetShading(bool)``: light the slices' texels from the volume's gradients (VTK's light model, the material
      of ``SetMaterial``); ``SetJitter(bool)``: sample each texel anywhere in its slab by its pixel's jitter.

    The number of slices and the slice distance apply to view-aligned slices and are ignored in ``"axis"`` mode,
    whose slices are the voxel layers.

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    >>> f = TextureSlicingFilter()
    >>> f.SetInputDataObject(image_from_array(volume, spacing, origin))
    >>> f.SetTransferTable(table)
    >>> f.SetCamera(camera)                 # in the image's frame
    >>> f.SetImageSize(256, 256)
    >>> f.SetNumberOfSlices(128)
    >>> rgba_image = run_algorithm(f)
    """

    label = "TextureSlicingFilter"

    def __init__(self) -> None:
        super().__init__()
        self._mode = "view"
        self._slices = 0
        self._slice_distance: float | None = None
        self._precision = "float"
        self._shading = False

    def SetShading(self, shading: bool) -> None:  # noqa: N802 - VTK naming
        self._set("_shading", bool(shading))

    def GetShading(self) -> bool:  # noqa: N802
        return self._shading

    def SetMode(self, mode: str) -> None:  # noqa: N802 - VTK naming
        self._set("_mode", checked_mode(mode))

    def GetMode(self) -> str:  # noqa: N802
        return self._mode

    def SetNumberOfSlices(self, count: int) -> None:  # noqa: N802
        """View-aligned slice count; 0 for the default (one slice per smallest voxel spacing)."""
        if isinstance(count, bool) or int(count) != count or count < 0:
            raise ValueError(f"the number of slices must be a non-negative integer, got {count!r}")
        self._set("_slices", int(count))

    def GetNumberOfSlices(self) -> int:  # noqa: N802
        return self._slices

    def SetSliceDistance(self, slice_distance: float | None) -> None:  # noqa: N802
        """Largest distance between view-aligned slices in mm; None for the default (the smallest spacing)."""
        if slice_distance is not None:
            slice_distance = validated_distance(slice_distance, "slice_distance")
        self._set("_slice_distance", slice_distance)

    def GetSliceDistance(self) -> float | None:  # noqa: N802
        return self._slice_distance

    def SetPrecision(self, precision: str) -> None:  # noqa: N802
        self._set("_precision", checked_precision(precision))

    def GetPrecision(self) -> str:  # noqa: N802
        return self._precision

    def _setup_key(self) -> tuple:
        return (self._mode, self._slices, self._slice_distance, self._precision, self._shading, self._material)

    def _create_renderer(self, array, spacing, table, progress) -> SlicingRenderer:
        view = self._mode == "view"
        return SlicingRenderer(
            array, spacing, table, mode=self._mode, precision=self._precision,
            slices=(self._slices or None) if view else None,
            slice_distance=self._slice_distance if view else None,
            shading=self._shading, jitter=self._jitter, progress=progress, **self._material_keywords(),
        )
