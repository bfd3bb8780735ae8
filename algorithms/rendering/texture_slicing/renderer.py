"""The float path of texture slicing: :class:`SlicingRenderer`, set up once per volume, one frame per camera.

It composites exactly the slices and textures the OpenGL path (:class:`~.gl_prop.SliceStackProp`) draws, per pixel
in float32 (or rounding to 8 bits after every slice, as a framebuffer does). See
:mod:`algorithms.rendering.texture_slicing` for the method.
"""

from __future__ import annotations

import math
import time
from typing import Iterator

import numpy as np

from ...common.camera import Camera, checked_camera
from ...common.mesh import csr_ranks
from ...common.progress import ProgressCallback, report
from ...common.render_result import RenderResult
from ...common.cutaway import ToolSet, packed_tools
from ...common.transfer import TransferTable, checked_table
from ...common.validation import (
    validated_count,
    validated_distance,
    validated_image_size,
    validated_spacing,
)
from ...common.sampling import sampled_volume
from . import kernels
from .geometry import MERGE_TOLERANCE, MODES, SlicePolygons, axis_aligned_slices, slice_count, slice_polygons
from .textures import (
    CHUNK_TEXELS,
    SliceLayout,
    SliceTexture,
    TextureChunk,
    bounding_textures,
    layout_stats,
    pixel_bounds,
    pixel_textures,
)

#: Compositing in float32, or with the accumulation rounded to 8 bits after every slice (a framebuffer).
PRECISIONS = ("float", "uint8")


def checked_mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    return mode


def checked_precision(precision: str) -> str:
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    return precision


class SlicingRenderer:
    """Texture-slicing volume renderer with float (or 8-bit emulating) compositing, set up once per volume.

    Parameters
    ----------
    volume_array : ndarray, shape (nz, ny, nx)
        Scalar volume indexed ``[k, j, i]`` (any real dtype; kept as float32), at least 2 voxels per axis.
    spacing : (sx, sy, sz)
        Voxel size in mm; voxel ``(i, j, k)`` sits at ``(i sx, j sy, k sz)`` in the volume frame.
    table : TransferTable
        Colour and opacity per ``table.unit_distance`` mm.
    slice_distance : float, optional
        Distance between view-aligned slices in mm: ``count = ceil(depth / slice_distance)`` slices. Default
        (with ``slices`` also None): the smallest voxel spacing, one slice per smallest spacing along the view (see
        the module notes; the ray marcher's default sample distance is half that).
    slices : int, optional
        Fixed number of view-aligned slices per frame instead of ``slice_distance``.
    mode : {"view", "axis"}
        View-aligned planes (regenerated per camera) or the axis-aligned stack through the voxel centres.
    precision : {"float", "uint8"}
        Accumulate in float32, or round the accumulation buffer to 8 bits after every slice (a framebuffer).
    texel_size : float, optional
        Texel size (mm) of view-aligned slice textures on a grid anchored at each polygon's corner. Default: one
        texel per pixel, its centre where the pixel's ray meets the slice (the texture resolution of a 3D texture
        sampled per fragment). Axis-aligned textures are the voxel grid of their layer.
    shading : bool
        Light each texel from the gradient of the volume (source 002, 2.4.4) with VTK's light model, as the ray
        marcher's ``"phong"``: ambient, two-sided diffuse, Phong specular, a headlight at the camera.
    ambient, diffuse, specular, specular_power : float
        The material (``vtkVolumeProperty``'s terms; defaults VTK's 0.1, 0.7, 0.2, 10).
    jitter : bool
        Sample each texel of a pixel-aligned view slice anywhere in its slab, by its pixel's jitter
        (:func:`algorithms.common.sampling.jitter_offset`), instead of on the slab's middle plane: no wood-grain
        rings. Ignored for axis-aligned stacks and a given ``texel_size`` (their texels are not the pixels' rays).
    progress : callable, optional
        Called with a fraction in [0, 1] during the set-up.

    Raises
    ------
    ValueError
        On a volume that is not 3D, has fewer than 2 voxels along an axis, is not real-valued or holds NaN/inf;
        spacing that is not three positive numbers; an unknown mode or precision; a non-positive
        ``slice_distance``, ``slices`` or ``texel_size``; both ``slice_distance`` and ``slices``;
        ``slice_distance``, ``slices`` or ``texel_size`` with ``mode="axis"`` (its slices and texels are the voxel
        layers).
    TypeError
        If ``table`` is not a :class:`~algorithms.common.transfer.TransferTable`.
    """

    def __init__(
        self,
        volume_array,
        spacing,
        table: TransferTable,
        *,
        slice_distance: float | None = None,
        slices: int | None = None,
        mode: str = "view",
        precision: str = "float",
        texel_size: float | None = None,
        shading: bool = False,
        ambient: float = 0.1,
        diffuse: float = 0.7,
        specular: float = 0.2,
        specular_power: float = 10.0,
        jitter: bool = False,
        progress: ProgressCallback = None,
    ) -> None:
        checked_table(table)
        self.spacing = validated_spacing(spacing)
        checked_mode(mode)
        checked_precision(precision)
        if slice_distance is not None and slices is not None:
            raise ValueError("give either slice_distance (mm between slices) or slices (a count), not both")
        if mode == "axis" and (slice_distance is not None or slices is not None or texel_size is not None):
            raise ValueError("axis-aligned slices and texels are the voxel layers; slice_distance, slices and "
                             "texel_size apply to mode='view' only")
        if slice_distance is not None:
            slice_distance = validated_distance(slice_distance, "slice_distance")
        if slices is not None:
            slices = validated_count(slices, "slices")
        if texel_size is not None:
            texel_size = validated_distance(texel_size, "texel_size")
        for name, value in (("ambient", ambient), ("diffuse", diffuse), ("specular", specular)):
            if not 0.0 <= float(value) <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {value}")
        if not (math.isfinite(float(specular_power)) and float(specular_power) > 0):
            raise ValueError(f"specular_power must be positive, got {specular_power}")
        self.volume = sampled_volume(volume_array)
        report(progress, 1.0)
        self.shading = bool(shading)
        self.material = np.array([ambient, diffuse, specular, specular_power], dtype=np.float64)
        self.jitter = bool(jitter)
        self.shape = self.volume.shape
        self.table = table
        self.slice_distance = slice_distance
        self.slices = slices
        self.mode = mode
        self.precision = precision
        self.texel_size = texel_size
        nz, ny, nx = self.shape
        self.box_min = np.zeros(3)
        self.box_max = (np.array([nx, ny, nz]) - 1) * self.spacing

    # -- geometry ------------------------------------------------------------------------------------------
    def slices_for(self, camera: Camera) -> SlicePolygons:
        """The slice stack this renderer draws for ``camera`` (volume frame), back to front."""
        camera = checked_camera(camera)
        if self.mode == "axis":
            return axis_aligned_slices(camera, self.box_min, self.box_max, self.spacing)
        if self.slices is not None:
            count = self.slices
        else:
            distance = self.slice_distance if self.slice_distance is not None else float(self.spacing.min())
            count = slice_count(camera, self.box_min, self.box_max, distance)
        return slice_polygons(camera, self.box_min, self.box_max, count)

    def layout(self, camera: Camera, width: int, height: int) -> SliceLayout:
        """The slices for ``camera`` (volume frame), their pixel ranges and texture grids in a ``width`` x
        ``height`` image."""
        camera = checked_camera(camera)
        width, height = validated_image_size(width, height)
        polygons = self.slices_for(camera)
        rows, columns = pixel_bounds(polygons, camera, width, height)
        pixel_aligned = polygons.axis is None and self.texel_size is None
        if pixel_aligned:
            grids = pixel_textures(polygons, camera, width, height, rows, columns)
        elif polygons.axis is None:
            grids = bounding_textures(polygons, self.texel_size, self.texel_size)
        else:
            grids = bounding_textures(polygons, float(abs(polygons.u_axis @ self.spacing)),
                                       float(abs(polygons.v_axis @ self.spacing)))
        origins, u_steps, v_steps, shapes = grids
        empty = (rows[:, 1] <= rows[:, 0]) | (columns[:, 1] <= columns[:, 0])
        shapes = np.where(empty[:, None], 0, shapes)
        return SliceLayout(polygons, rows, columns, origins, u_steps, v_steps, shapes, pixel_aligned)

    # -- textures ------------------------------------------------------------------------------------------
    def corrected_table(self, polygons: SlicePolygons) -> np.ndarray:
        """The transfer table ``(n, 4)`` float32 with opacity corrected for ``polygons.path_step``."""
        return np.ascontiguousarray(self.table.corrected(polygons.path_step), dtype=np.float32)

    def texture_chunks(self, layout: SliceLayout, camera: Camera | None = None, *, size=None, pass_index: int = 0,
                       jitter: bool | None = None, tools: ToolSet | None = None) -> Iterator[TextureChunk]:
        """The textures of the visible slices, back to front, a chunk of consecutive slices at a time.

        ``camera`` (the layout's, volume frame) places the headlight of ``shading``; with the image ``size``
        ``(width, height)`` it also gives the pixel rays of ``jitter`` (default: the renderer's), pass
        ``pass_index``. Without a camera neither applies.

        A texel holds the premultiplied RGBA of the trilinearly interpolated scalar at its centre (clamped to
        the volume: texels beyond the box, read only by bilinear filtering at the polygon's border, hold border
        values), with the opacity corrected for the stack's ``path_step``; ``tools`` (volume frame) cut texels away
        per texel (source 002, 2.5.1). Chunks hold about
        ``CHUNK_TEXELS`` texels, so memory stays bounded and each kernel launch has enough work for every thread.
        """
        table = self.corrected_table(layout.polygons)
        inverse_spacing = 1.0 / self.spacing
        shading = self.shading and camera is not None
        jitter = (self.jitter if jitter is None else jitter) and camera is not None and size is not None
        jitter = jitter and layout.pixel_aligned
        eye = np.asarray(camera.position if camera is not None else (0.0, 0.0, 0.0), dtype=np.float64)
        frame = np.ascontiguousarray(camera.ray_frame(*size)) if jitter else np.zeros((5, 3))
        parallel = bool(camera.parallel_projection) if camera is not None else True
        packed = packed_tools(tools)
        visible = np.flatnonzero(layout.visible)
        sizes = layout.shapes[visible, 0] * layout.shapes[visible, 1]
        chunk_of = (np.cumsum(sizes) - sizes) // CHUNK_TEXELS
        for chunk in np.unique(chunk_of):
            indices = visible[chunk_of == chunk]
            heights, widths = layout.shapes[indices, 0], layout.shapes[indices, 1]
            starts = np.concatenate([[0], np.cumsum(heights * widths)[:-1]]).astype(np.int64)
            textures = np.empty((int((heights * widths).sum()), 4), dtype=np.float32)
            row_slices = np.repeat(np.arange(len(indices)), heights)
            row_indices = csr_ranks(heights)
            kernels.fill_textures(self.volume, inverse_spacing, self.box_min, self.box_max, layout.origins[indices],
                                  layout.u_steps[indices], layout.v_steps[indices], widths, starts, row_slices,
                                  row_indices, table, float(self.table.value_min), float(self.table.scale), shading,
                                  self.material, eye, jitter, int(pass_index), frame, parallel,
                                  layout.columns[indices, 0].astype(np.int64),
                                  (layout.rows[indices, 1] - 1).astype(np.int64),
                                  float(layout.polygons.slice_distance), packed, textures)
            yield TextureChunk(indices, starts, textures)

    def iter_textures(self, layout: SliceLayout, camera: Camera | None = None, *,
                      size=None, tools: ToolSet | None = None) -> Iterator[tuple[int, SliceTexture]]:
        """``(slice index, texture)`` of every visible slice, back to front (see :meth:`texture_chunks`: with the
        camera and image ``size`` the OpenGL path draws exactly the float path's shaded, jittered textures)."""
        for chunk in self.texture_chunks(layout, camera, size=size, tools=tools):
            for m, index in enumerate(chunk.indices):
                height, width = layout.shapes[index]
                rgba = chunk.textures[chunk.starts[m]: chunk.starts[m] + height * width].reshape(height, width, 4)
                yield int(index), SliceTexture(layout.origins[index], layout.u_steps[index], layout.v_steps[index],
                                               rgba)

    # -- frames --------------------------------------------------------------------------------------------
    def render(self, camera: Camera, width: int, height: int, *, pass_index: int = 0, tools: ToolSet | None = None,
               progress: ProgressCallback = None) -> RenderResult:
        """One frame seen by ``camera`` (volume frame) at ``width`` x ``height`` pixels (jitter pass
        ``pass_index``), cut by ``tools`` (volume frame) per texel.

        Returns
        -------
        RenderResult
            ``rgba`` ``(height, width, 4)`` float32 premultiplied, row 0 at the top; ``stats``: see
            :func:`layout_stats`, plus ``seconds``.
        """
        start = time.perf_counter()
        layout = self.layout(camera, width, height)
        polygons = layout.polygons
        frame = np.ascontiguousarray(camera.ray_frame(int(width), int(height)))
        image = np.zeros((int(height), int(width), 4), dtype=np.float32)
        tolerance = MERGE_TOLERANCE * float(np.linalg.norm(self.box_max - self.box_min))
        total = max(int(layout.visible.sum()), 1)
        done = 0
        for chunk in self.texture_chunks(layout, camera, size=(int(width), int(height)), pass_index=pass_index,
                                         tools=tools):
            indices = chunk.indices
            u_steps, v_steps = layout.u_steps[indices], layout.v_steps[indices]
            kernels.composite_slices(
                image, frame, bool(camera.parallel_projection), polygons.normal, polygons.offsets[indices],
                self.box_min, self.box_max, tolerance, layout.origins[indices],
                u_steps / np.sum(u_steps**2, axis=1, keepdims=True),
                v_steps / np.sum(v_steps**2, axis=1, keepdims=True),
                layout.shapes[indices, 0], layout.shapes[indices, 1], chunk.starts, chunk.textures,
                layout.rows[indices], layout.columns[indices], self.precision == "uint8",
            )
            done += len(indices)
            report(progress, done / total)
        return RenderResult(image, {"seconds": time.perf_counter() - start, **layout_stats(layout)})
