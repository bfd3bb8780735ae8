"""The shear-warp renderer: set-up (the rendered grid, classification and encodings) once per volume and transfer
function, then one frame per camera (factorise, correct opacity, composite, warp), parallel or perspective.

See :mod:`algorithms.rendering.shear_warp` for the method, :mod:`.perspective` for the perspective factorisation and
:mod:`.jitter` for the jittered (post-classified) compositing.
"""

from __future__ import annotations

import time
from typing import Sequence

import numba
import numpy as np

from ...common.camera import Camera
from ...common.progress import ProgressCallback, report, scaled
from ...common.render_result import RenderResult
from ...common.transfer import TransferTable, checked_table
from ...common.sampling import sampled_volume
from ...common.validation import validated_distance, validated_image_size, validated_spacing
from . import kernels, resampling
from .cut import composite_with_tools, tools_for_frame
from .encoding import MAX_SCANLINE, DenseVolume, NormalTable, RunLengthVolume, checked_grid
from .factorisation import AXIS_NAMES, STANDARD_AXES, factorize
from .jitter import composite_jittered
from .perspective import composite_scanlines, factorize_perspective, parallel_scanline_offsets, warp_projective

#: Largest transfer table: entries and the all-zero row of transparent voxels are uint16 indices.
MAX_TABLE_ENTRIES = 65535
#: Rows of the intermediate image handed to a thread at a time.
_ROW_BLOCK = 4
#: ``resample_spacing="auto"`` resamples a volume whose largest spacing exceeds its smallest by more than this.
ANISOTROPY_LIMIT = 1.2


class ShearWarpRenderer:
    """Shear-warp renderer of one volume and transfer function, parallel or perspective.

    Construction is the set-up: the rendered grid (the volume's own, or resampled along coarse axes), the normal
    table (with shading) and the classified, run-length encoded copies, one per principal axis, built straight from
    the scalar volume (no volume-sized intermediate: a copy costs what it stores). :meth:`render` factors the view,
    corrects opacity for it, composites and warps.

    Parameters
    ----------
    volume_array : ndarray (nz, ny, nx)
        Scalar volume, indexed ``[k, j, i]``; any real dtype. A read-only array is used as it is (the VTK filter
        passes VTK's memory), anything else is copied once.
    spacing : (sx, sy, sz)
        Voxel size in mm.
    table : TransferTable
        Colour and opacity per ``unit_distance`` mm. Values are classified to the nearest table entry.
    resample_spacing : float, "auto" or None
        Resampling (source 004, section 6.3.1): render a grid of about ``resample_spacing`` mm along every axis over
        the same box (trilinear values, classified afterwards; computed on the fly while encoding), so slices and
        intermediate pixels are that far apart: the source's remedy for anisotropic volumes, whose coarse slices
        the intermediate image would otherwise keep at their own spacing and the warp stretch. ``"auto"`` (the
        default) resamples to the smallest spacing when the largest exceeds it by more than
        :data:`ANISOTROPY_LIMIT` (only the coarse axes gain voxels) and keeps isotropic grids as they are; None
        always renders the volume's own grid.
    shading : bool
        Shading from quantised gradient normals (a headlight unless ``light_direction`` is given).
    normal_grid : int
        Cells per side of the normal grid (even, 2 to 200): about ``2 pi (grid / 2)^2`` normals. A grid of 8 shows
        banding clearly; the default 128 (26299 normals, mean error 0.8 degrees) not visibly. Checked even without
        shading.
    ambient, diffuse, specular, specular_power : float
        Blinn-Phong terms (VTK's meaning, the application's defaults).
    light_direction : (3,) floats, optional
        Direction *towards* the light in the volume frame; None = a headlight from the camera (VTK's default light).
    opacity_threshold : float
        A voxel whose transfer-function opacity is ``<= opacity_threshold`` is transparent (not stored, skipped),
        and a resampled sample is composited only when its opacity exceeds it. 0 (default) changes nothing in the
        image.
    early_termination : float or None
        A pixel of the intermediate image is opaque once its opacity reaches this value; later samples behind it
        are skipped through the offsets. None turns early ray termination (and opaque-pixel skipping) off.
    use_rle : bool
        False keeps dense classified copies and visits every voxel (brute force, for the ablation; parallel,
        unjittered frames only); the image is the same.
    jitter : bool
        Sample each ray once between its crossings of consecutive slices, at its pixel's jitter, and classify the
        trilinear scalar value there (post-classification, see :mod:`.jitter`): no wood-grain terraces, the same
        frame for the same camera and size.
    lazy : bool
        Build a principal axis's copy when a view first needs it instead of all three up front (what the
        application does: a still image needs one copy, so a large volume costs a third of the memory).
    progress : callable, optional
        Progress of the set-up; may raise :class:`OperationCancelled`.

    Attributes
    ----------
    setup_stats : dict
        ``setup_seconds``, ``classification_seconds`` (0: classification happens while encoding),
        ``encoding_seconds`` (all copies built so far), ``normal_seconds`` (0: normals are quantised while
        encoding), ``prescale_seconds`` (0: resampling happens while encoding), ``raw_bytes`` (the scalar volume),
        ``encoded_bytes_x/y/z`` (each copy built: runs + stored voxels + scanline pointers; the dense copies with
        ``use_rle=False``), ``non_transparent_fraction`` (of the last copy built), ``normal_count``,
        ``rendered_voxels`` and ``rendered_spacing_x/y/z`` (mm).

    Examples
    --------
    >>> renderer = ShearWarpRenderer(volume.array, volume.spacing, table)
    >>> result = renderer.render(camera, 512, 512)      # camera in the volume frame, parallel or perspective
    >>> result.rgba.shape, result.stats["principal_axis"]
    ((512, 512, 4), 1.0)
    """

    def __init__(
        self,
        volume_array: np.ndarray,
        spacing: Sequence[float],
        table: TransferTable,
        *,
        resample_spacing: float | str | None = "auto",
        shading: bool = False,
        normal_grid: int = 128,
        ambient: float = 0.2,
        diffuse: float = 0.7,
        specular: float = 0.3,
        specular_power: float = 10.0,
        light_direction: Sequence[float] | None = None,
        opacity_threshold: float = 0.0,
        early_termination: float | None = 0.99,
        use_rle: bool = True,
        jitter: bool = False,
        lazy: bool = False,
        progress: ProgressCallback = None,
    ) -> None:
        start = time.perf_counter()
        volume = sampled_volume(volume_array)
        spacing = tuple(float(v) for v in validated_spacing(spacing))
        checked_table(table, error=ValueError)
        for name, value in (("ambient", ambient), ("diffuse", diffuse), ("specular", specular)):
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {value}")
        if not specular_power > 0:
            raise ValueError(f"specular_power must be positive, got {specular_power}")
        if light_direction is not None:
            light_direction = np.asarray(light_direction, dtype=np.float64).reshape(-1)
            if light_direction.shape != (3,) or not np.all(np.isfinite(light_direction)) or not np.any(light_direction):
                raise ValueError(f"light_direction must be a finite non-zero 3-vector, got {light_direction!r}")
        if not 0.0 <= opacity_threshold < 1.0:
            raise ValueError(f"opacity_threshold must lie in [0, 1), got {opacity_threshold}")
        if early_termination is not None and not 0.0 < early_termination <= 1.0:
            raise ValueError(f"early_termination must lie in (0, 1] or be None, got {early_termination}")
        normal_grid = checked_grid(normal_grid)
        normal_table = NormalTable.build(normal_grid) if shading else None
        if isinstance(resample_spacing, str):
            if resample_spacing != "auto":
                raise ValueError(f"resample_spacing must be a distance in mm, 'auto' or None, got {resample_spacing!r}")
            resample_spacing = min(spacing) if max(spacing) > ANISOTROPY_LIMIT * min(spacing) else None
        elif resample_spacing is not None:
            resample_spacing = validated_distance(resample_spacing, "resample_spacing")

        # The rendered grid: m points per axis over the same box, m = ceil(extent / resample_spacing) + 1.
        sizes = np.array(volume.shape[::-1], dtype=np.int64)  # (nx, ny, nz)
        grid = sizes.copy()
        if resample_spacing is not None:
            extents = (sizes - 1) * np.asarray(spacing)
            grid = np.maximum(np.ceil(extents / resample_spacing - 1e-9).astype(np.int64) + 1, 2)
        for axis, size in zip("xyz", grid):
            if size > MAX_SCANLINE:
                raise ValueError(f"the rendered grid has {size} voxels along {axis}; at most {MAX_SCANLINE} are "
                                 "supported (choose a coarser resample_spacing)")
        self._scales = np.where(grid > 1, (sizes - 1) / np.maximum(grid - 1, 1), 1.0).astype(np.float64)
        self._resampled = bool(np.any(grid != sizes))
        self.resample_spacing = resample_spacing
        self.volume_spacing = spacing
        self.spacing = tuple(float(s * c) for s, c in zip(spacing, self._scales))
        self.shape = (int(grid[2]), int(grid[1]), int(grid[0]))
        self.shading = bool(shading)
        self.normal_table = normal_table
        self.ambient, self.diffuse, self.specular = float(ambient), float(diffuse), float(specular)
        self.specular_power = float(specular_power)
        self.light_direction = light_direction
        self.opacity_threshold = float(opacity_threshold)
        self.early_termination = early_termination
        self.use_rle = bool(use_rle)
        self.jitter = bool(jitter)
        self.lazy = bool(lazy)
        self._values = volume
        self.table: TransferTable | None = None
        self._copies: list = [None, None, None]
        self.setup_stats: dict[str, float] = {
            "prescale_seconds": 0.0, "normal_seconds": 0.0, "classification_seconds": 0.0,
            "raw_bytes": float(volume.nbytes),
            "normal_count": float(len(normal_table.normals)) if normal_table else 0.0,
            "rendered_voxels": float(np.prod(grid)),
            **{f"rendered_spacing_{name}": value for name, value in zip("xyz", self.spacing)},
        }
        report(progress, 0.05)
        self.set_table(table, progress=scaled(progress, 0.05, 1.0))
        self.setup_stats["setup_seconds"] = time.perf_counter() - start

    # -- classification ----------------------------------------------------------------------------------------
    def set_table(self, table: TransferTable, *, progress: ProgressCallback = None) -> None:
        """Use ``table``: the encoded copies are rebuilt (all three now, or each when first needed with ``lazy``);
        nothing happens if it is unchanged."""
        checked_table(table, error=ValueError)
        if table.size > MAX_TABLE_ENTRIES:
            raise ValueError(f"transfer tables of at most {MAX_TABLE_ENTRIES} entries are supported, got {table.size}")
        if self.table is not None and table.same_as(self.table):
            return
        self.table = table
        self._visible = np.ascontiguousarray(table.rgba[:, 3] > self.opacity_threshold)
        self._copies = [None, None, None]
        self.setup_stats["encoding_seconds"] = 0.0
        for axis in range(3):
            self.setup_stats[f"encoded_bytes_{AXIS_NAMES[axis]}"] = 0.0
        if not self.lazy:
            for axis in range(3):
                self._copy(axis)
                report(progress, (axis + 1) / 3)

    def _copy(self, axis: int):
        """The copy of ``axis`` (built on first use): run-length encoded, or dense with ``use_rle=False``."""
        if self._copies[axis] is None:
            begin = time.perf_counter()
            encoded = self._encode(axis)
            if self.use_rle:
                copy = encoded
            else:
                # Brute force: transparent voxels point at the all-zero row after the table's entries.
                dense = encoded.decode(self.table.size)
                normals = np.empty((0, 0, 0), np.uint16)
                if self.shading:
                    normals = _decode_normals(encoded)
                copy = DenseVolume(dense, normals)
            self._copies[axis] = copy
            self.setup_stats["encoding_seconds"] += time.perf_counter() - begin
            self.setup_stats[f"encoded_bytes_{AXIS_NAMES[axis]}"] = float(copy.nbytes)
            total = float(np.prod(self.shape))
            self.setup_stats["non_transparent_fraction"] = encoded.stored_voxels / total if total else 0.0
        return self._copies[axis]

    def _encode(self, axis: int) -> RunLengthVolume:
        """Classify, quantise normals and run-length encode the rendered grid for principal ``axis``."""
        axes = np.array(STANDARD_AXES[axis], dtype=np.int64)
        nx, ny, nz = self.shape[::-1]
        shape = np.array([(nx, ny, nz)[axes[2]], (nx, ny, nz)[axes[1]], (nx, ny, nz)[axes[0]]], dtype=np.int64)
        table = self.table
        arguments = (self._values, axes, shape, self._scales, self._resampled, float(table.value_min),
                     float(table.scale), table.size - 1, self._visible)
        run_counts, voxel_counts = resampling.count_runs_resampled(*arguments)
        nk, nj, ni = (int(v) for v in shape)
        line_runs = np.zeros(nk * nj, dtype=np.int64)
        line_voxels = np.zeros(nk * nj, dtype=np.int64)
        np.cumsum(run_counts[:-1], out=line_runs[1:])
        np.cumsum(voxel_counts[:-1], out=line_voxels[1:])
        run_lengths = np.empty(int(run_counts.sum()) + 1, dtype=np.uint16)
        run_lengths[-1] = kernels.SENTINEL_RUN
        stored = int(voxel_counts.sum())
        classes = np.empty(stored, dtype=np.uint16)
        normals = np.empty(stored if self.shading else 0, dtype=np.uint16)
        table_normals = self.normal_table
        encoding = table_normals.encoding if table_normals else np.zeros((2, 1, 1), dtype=np.int32)
        resampling.fill_runs_resampled(
            *arguments, np.asarray(self.volume_spacing, dtype=np.float64), self.shading, encoding,
            float(table_normals.grid // 2) if table_normals else 0.0,
            np.uint16(table_normals.zero_index if table_normals else 0), line_runs, line_voxels, run_lengths, classes,
            normals)
        return RunLengthVolume(axis, (nk, nj, ni), run_lengths, classes, normals, line_runs, line_voxels)

    def encoding(self, principal_axis: int) -> RunLengthVolume:
        """The run-length encoded copy for ``principal_axis`` (0, 1, 2 = x, y, z), built if needed."""
        if not self.use_rle:
            raise ValueError("this renderer was built with use_rle=False and keeps no run-length encoding")
        if principal_axis not in (0, 1, 2):
            raise ValueError(f"principal_axis must be 0, 1 or 2, got {principal_axis!r}")
        return self._copy(principal_axis)

    # -- rendering ---------------------------------------------------------------------------------------------
    def render(self, camera: Camera, width: int, height: int, *, pass_index: int = 0,
               progress: ProgressCallback = None, tools=None) -> RenderResult:
        """Render one frame of ``camera`` (volume frame; parallel or perspective) at ``width x height`` pixels.

        ``tools`` (a :class:`~algorithms.common.cutaway.ToolSet` in the volume frame, parallel unjittered frames
        only) are tested per sample at compositing (:mod:`.cut`; the encoding is not changed).

        ``pass_index`` is the jitter pass (see :mod:`algorithms.common.sampling`).

        Returns
        -------
        RenderResult
            ``rgba`` (height, width, 4) float32 premultiplied, row 0 at the top. ``stats``: ``seconds``,
            ``composite_seconds``, ``warp_seconds``, ``voxels_composited`` (resampled samples composited),
            ``voxels_skipped_transparent`` (samples skipped as transparent), ``pixels_skipped_opaque`` (samples
            skipped behind opaque pixels), ``principal_axis`` (0, 1, 2 = x, y, z), ``sample_distance`` (mm; the
            smallest of the frame in perspective), ``intermediate_width``, ``intermediate_height``, ``perspective``
            (0 or 1).

        Raises
        ------
        ValueError
            For a perspective camera inside the volume's box, or a perspective or jittered frame of a
            ``use_rle=False`` renderer.
        """
        start = time.perf_counter()
        width, height = validated_image_size(width, height)
        if isinstance(pass_index, bool) or int(pass_index) != pass_index or pass_index < 0:
            raise ValueError(f"pass_index must be a non-negative integer, got {pass_index!r}")
        if not isinstance(camera, Camera):
            raise ValueError(f"camera must be an algorithms.common.camera.Camera, got {type(camera).__name__}")
        perspective = not camera.parallel_projection
        scanlines = perspective or self.jitter
        tools = tools if tools is not None and len(tools) else None
        if tools is not None and (scanlines or not self.use_rle):
            raise ValueError("shear-warp honours cut-away tools in parallel, unjittered frames only (use a parallel "
                             "camera and no jitter, or another volume mode)")
        if scanlines and not self.use_rle:
            raise ValueError("use_rle=False (the brute-force ablation) renders parallel, unjittered frames only")
        if perspective:
            f = factorize_perspective(camera, self.shape, self.spacing, width, height)
            column_offset, row_offset, inverse_scale = f.column_offset, f.row_offset, f.inverse_scale
            ratio, use_ratio = f.distance_ratio, True
        else:
            f = factorize(camera, self.shape, self.spacing, width, height)
            column_offset, row_offset, inverse_scale = parallel_scanline_offsets(f.slice_order, f.shear,
                                                                                  f.translation)
            ratio, use_ratio = np.ones((1, 1), dtype=np.float32), False
        table = self._view_table(f.sample_distance)
        if self.shading:
            viewer = -camera.direction
            light = viewer if self.light_direction is None else self.light_direction
            shade = self.normal_table.shade(light, viewer, ambient=self.ambient, diffuse=self.diffuse,
                                            specular=self.specular, specular_power=self.specular_power)
        else:
            shade = np.zeros((1, 2), dtype=np.float32)
        rows, cols = f.intermediate_shape
        image = np.zeros((rows, cols, 4), dtype=np.float32)
        offsets = np.zeros((rows, cols), dtype=np.int32)
        opaque = 2.0 if self.early_termination is None else float(self.early_termination)
        copy = self._copy(f.principal_axis)
        counts = np.zeros((numba.get_num_threads(), 3), dtype=np.int64)
        totals = np.zeros(3, dtype=np.int64)
        removed = 0
        # One parallel region per frame; with a progress callback, bands of rows so it can report and cancel.
        bands = np.linspace(0, rows, (min(8, rows) if progress is not None else 1) + 1).astype(np.int64)
        begin = time.perf_counter()
        # once per frame, shared by the bands
        slice_offsets = None if scanlines else f.slice_offsets()
        frame_tools = None if tools is None else tools_for_frame(tools, f, self.spacing, self.normal_table,
                                                                 self.shading)
        for band, (first, last) in enumerate(zip(bands[:-1], bands[1:])):
            if self.jitter:
                composite_jittered(self._values, np.array(STANDARD_AXES[f.principal_axis], dtype=np.int64),
                                   self._scales, float(self.table.value_min), float(self.table.scale),
                                   self.table.size - 1, np.asarray(self.volume_spacing, dtype=np.float64),
                                   copy.run_lengths, copy.line_runs, copy.line_voxels, copy.classes.shape[0],
                                   copy.shape[1], copy.shape[2], f.slice_order, column_offset, row_offset,
                                   inverse_scale, table, shade, self.shading, *self._normal_encoding(),
                                   self.opacity_threshold, opaque, ratio, use_ratio, int(pass_index), image, offsets,
                                   first, last, _ROW_BLOCK, counts)
            elif scanlines:
                composite_scanlines(copy.run_lengths, copy.classes, copy.normals, copy.line_runs, copy.line_voxels,
                                    copy.shape[1], copy.shape[2], f.slice_order, column_offset, row_offset,
                                    inverse_scale, table, shade, self.shading, self.opacity_threshold, opaque, ratio,
                                    use_ratio, image, offsets, first, last, _ROW_BLOCK, counts)
            elif tools is not None:
                # the tools' test per sample (source 002, 2.5): see .cut
                removed += composite_with_tools(copy, f, slice_offsets, table, shade, self.shading,
                                                self.opacity_threshold, opaque, image, offsets, first, last,
                                                _ROW_BLOCK, counts, frame_tools)
            else:
                pixel_i, pixel_j, fraction_i, fraction_j = slice_offsets
                arguments = (f.slice_order, pixel_i, pixel_j, fraction_i, fraction_j, table, shade, self.shading,
                             self.opacity_threshold, opaque, image, offsets, first, last, _ROW_BLOCK, counts)
                if self.use_rle:
                    kernels.composite_rle(copy.run_lengths, copy.classes, copy.normals, copy.line_runs,
                                          copy.line_voxels, copy.shape[1], copy.shape[2], *arguments)
                else:
                    kernels.composite_dense(copy.classes, copy.normals, *arguments)
            totals += counts.sum(axis=0)
            report(progress, 0.9 * (band + 1) / (len(bands) - 1))
        composite_seconds = time.perf_counter() - begin
        begin = time.perf_counter()
        if perspective:
            rgba = warp_projective(image, np.linalg.inv(f.warp), height, width)
        else:
            rgba = kernels.warp_bilinear(image, np.linalg.inv(f.warp), height, width)
        warp_seconds = time.perf_counter() - begin
        report(progress, 1.0)
        stats = {
            "seconds": time.perf_counter() - start,
            "composite_seconds": composite_seconds,
            "warp_seconds": warp_seconds,
            "voxels_composited": float(totals[0]),
            "voxels_skipped_transparent": float(totals[1]),
            "pixels_skipped_opaque": float(totals[2]),
            "principal_axis": float(f.principal_axis),
            "sample_distance": f.sample_distance,
            "intermediate_width": float(cols),
            "intermediate_height": float(rows),
            "perspective": float(perspective),
            "samples_removed_by_tools": float(removed),
        }
        return RenderResult(rgba, stats)

    def _normal_encoding(self) -> tuple[np.ndarray, float, np.uint16]:
        """The normal table's encoding grid, half grid and zero-gradient index (placeholders without shading)."""
        normals = self.normal_table
        if normals is None:
            return np.zeros((2, 1, 1), dtype=np.int32), 0.0, np.uint16(0)
        return normals.encoding, float(normals.grid // 2), np.uint16(normals.zero_index)

    def _view_table(self, sample_distance: float) -> np.ndarray:
        """Opacity-corrected, premultiplied RGBA per table entry, plus an all-zero row for transparent voxels."""
        corrected = self.table.corrected(sample_distance)
        out = np.zeros((len(corrected) + 1, 4), dtype=np.float32)
        out[:-1, :3] = corrected[:, :3] * corrected[:, 3:4]
        out[:-1, 3] = corrected[:, 3]
        out[:-1][~(self.table.rgba[:, 3] > self.opacity_threshold)] = 0.0
        return out


def _decode_normals(encoded: RunLengthVolume) -> np.ndarray:
    """The dense normal indices of an encoding (0 at transparent voxels), for the brute-force ablation."""
    swapped = RunLengthVolume(encoded.principal_axis, encoded.shape, encoded.run_lengths, encoded.normals,
                              encoded.normals, encoded.line_runs, encoded.line_voxels)
    return swapped.decode(0)
