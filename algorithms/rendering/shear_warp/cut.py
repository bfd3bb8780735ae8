"""Cut-away tools in shear-warp: the per-sample selection test at compositing (source 002, section 2.5).

The run-length encoded volume (source 004, section 5.2.2) is never changed when a tool moves: each sample that the
compositing loop of :func:`algorithms.rendering.shear_warp.kernels.composite_rle` resamples from a slice is tested
against the tools (:mod:`algorithms.common.cutaway`) at its position in the slice before it is composited; a
removed sample is skipped (binary evaluation) or weighted by the smooth ramp of the distance evaluation (source 002,
section 3.3.1). Within the cut band, with shading, the sample is shaded with the tool's normal (quantised on the
normal table's grid, source 004, 5.2.7) instead of the data gradient. The transparent-run and opaque-pixel skipping
of the encoding stay valid: a tool only removes matter.

Coordinates: the kernel evaluates the tools in the *standard* index frame of the principal axis, ``(i, j, k)`` =
(voxel along the scanline, scanline, slice) of the rendered grid; :func:`tools_in_standard_frame` maps a
:class:`~algorithms.common.cutaway.ToolSet` given in the volume frame (mm) to it, so distances stay in mm.
Only parallel, unjittered frames of the run-length encoded volume take tools (the path of source 004's
compositing); perspective and jittered frames refuse them with a ValueError.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...common.atomics import take
from ...common.cutaway import (
    FAR,
    ToolSet,
    clear_at,
    cut_band,
    cut_normals_on,
    leap_at,
    removal,
    removal_normal,
    visibility,
)
from ...common.cutaway_bounds import bounds_margin, ray_interval, reach_box
from .factorisation import STANDARD_AXES
from .kernels import (
    _A_LEFT,
    _A_RIGHT,
    _B_LEFT,
    _B_RIGHT,
    _accumulate,
    _advance,
    _composite,
    _composite_stretch,
    _slice_setup,
    _start,
)
from .kernels import find_opaque_run_end


def tools_in_standard_frame(tools: ToolSet, principal_axis: int, spacing) -> ToolSet:
    """``tools`` (volume frame, mm) for points given as standard indices ``(i, j, k)`` of ``principal_axis`` on a
    grid of ``spacing`` ``(sx, sy, sz)`` mm (voxel index times spacing = volume frame)."""
    frame = np.zeros((4, 4))
    frame[3, 3] = 1.0
    for column, axis in enumerate(STANDARD_AXES[principal_axis]):
        frame[axis, column] = float(spacing[axis])
    return tools.in_frame(frame)


@njit(cache=True, nogil=True, forceinline=True)
def _samples_within(span, most):
    """How many samples one unit apart, from the current one on, lie at most ``span`` ahead (``floor(span) + 1``),
    at least 1 and at most ``most``; safe for an infinite ``span`` (a half-space's chord never ends)."""
    if not span < most:
        return most
    return max(int(math.floor(span)) + 1, 1)


@njit(cache=True, nogil=True, forceinline=True)
def _samples_before(span, most):
    """How many samples one unit apart, from the current one on, lie less than ``span`` ahead (``ceil(span)``), at
    least 1 and at most ``most``; safe for a huge ``span``."""
    if not span < most:
        return most
    return max(int(math.ceil(span)), 1)


@njit(cache=True, nogil=True, inline="always")
def _tool_normal_index(tools, i, j, k, axes, spacing, encoding, half_grid, zero_index):
    """The normal-table index of the cut's normal at standard position ``(i, j, k)``: ``-grad g`` in the volume
    frame (pointing into the removed region, like the data normal ``-grad f`` points out of dense matter)."""
    gi, gj, gk = removal_normal(tools, i, j, k, 0.5)
    g = np.zeros(3)
    g[axes[0]] = gi / spacing[axes[0]]
    g[axes[1]] = gj / spacing[axes[1]]
    g[axes[2]] = gk / spacing[axes[2]]
    norm = np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    if norm == 0.0:
        return np.int64(zero_index)
    vx = np.int64(np.rint(half_grid - half_grid * g[0] / norm))
    vy = np.int64(np.rint(half_grid - half_grid * g[1] / norm))
    return np.int64(encoding[0 if g[2] <= 0.0 else 1, vx, vy])


@njit(cache=True, nogil=True, parallel=True)
def composite_rle_cut(
    run_lengths, voxel_classes, voxel_normals, line_runs, line_voxels, nj, ni,
    slice_order, pixel_i, pixel_j, fraction_i, fraction_j,
    table, shade, shading, opacity_threshold, opaque_threshold,
    image, offsets, row_start, row_stop, block, counts,
    tools, reach, axes, spacing, encoding, half_grid, zero_index,
):
    """:func:`~algorithms.rendering.shear_warp.kernels.composite_rle` with the tools' per-sample test (module notes).

    ``tools``: packed :class:`~algorithms.common.cutaway.ToolSet` in the standard index frame; ``reach``: ``(j
    low, j high, k low, k high)`` of its :func:`~algorithms.common.cutaway_bounds.reach_box` (a line of samples
    outside it meets no tool, and skips :func:`~algorithms.common.cutaway_bounds.ray_interval`); ``axes``: the
    principal axis's :data:`STANDARD_AXES`; ``spacing``: the rendered grid's ``(sx, sy, sz)``; ``encoding``,
    ``half_grid``, ``zero_index``: the normal table's quantisation (for the cut's normal with shading).
    ``counts[task, 3]`` receives the samples the tools removed.

    Each task's work is the separately compiled :func:`_cut_task` (one call per thread; ``task`` as int64, see
    :func:`~.kernels._task_rows`): numba's parfor passes (fusion, pre-lowering, outlining the loop body) cost time
    that grows steeply with the size of the ``prange`` body, and with the body written out here they took most of
    this kernel's 170 s cold compile.
    """
    tool_shading = shading and cut_normals_on(tools)
    band = cut_band(tools)
    margin = bounds_margin(tools, tool_shading)
    queue = np.zeros(1, dtype=np.int64)
    for task in prange(counts.shape[0]):
        _cut_task(
            np.int64(task), queue, run_lengths, voxel_classes, voxel_normals, line_runs, line_voxels, nj, ni,
            slice_order, pixel_i, pixel_j, fraction_i, fraction_j,
            table, shade, shading, opacity_threshold, opaque_threshold,
            image, offsets, row_start, row_stop, block, counts,
            tools, reach, axes, spacing, encoding, half_grid, zero_index, tool_shading, band, margin,
        )


@njit(cache=True, nogil=True)
def _cut_task(
    task, queue, run_lengths, voxel_classes, voxel_normals, line_runs, line_voxels, nj, ni,
    slice_order, pixel_i, pixel_j, fraction_i, fraction_j,
    table, shade, shading, opacity_threshold, opaque_threshold,
    image, offsets, row_start, row_stop, block, counts,
    tools, reach, axes, spacing, encoding, half_grid, zero_index, tool_shading, band, margin,
):
    """One task of :func:`composite_rle_cut`: takes blocks of rows from ``queue`` until none is left and
    composites them; fills ``counts[task]``."""
    cursor = np.zeros((4, 4), dtype=np.int64)
    composited = 0
    transparent = 0
    hidden = 0
    removed = 0
    while True:
        first = row_start + take(queue, 1) * block  # the next block of rows (module notes)
        if first >= row_stop:
            break
        for v in range(first, min(first + block, row_stop)):
            row_offsets = offsets[v]
            for k in slice_order:
                line_a, use_b, use_r, count, u0, w_al, w_ar, w_bl, w_br = _slice_setup(
                    v, k, nj, ni, pixel_i, pixel_j, fraction_i, fraction_j)
                if line_a < 0:
                    continue
                sample_j = line_a + fraction_j[k]
                sample_k = np.float64(k)
                line_a += k * nj
                line_b = line_a + use_b
                started = False
                # Where along this line of samples (i = a + fraction_i[k]) the tools can matter, found when the line
                # first has something to composite: tested there only; outside a keep tool everything is removed.
                bounded = False
                untested_until = -np.inf  # samples of the line before this are surely clear of every tool
                # (a line outside the tools' reach keeps these: nothing to test, nothing clipped or removed)
                tool_low, tool_high, keep_low, keep_high, removed_low, removed_high = (
                    np.inf, -np.inf, -np.inf, np.inf, 1.0, 0.0)
                a = 0
                while a < count:
                    u = u0 + a
                    if row_offsets[u] > 0:
                        run = find_opaque_run_end(row_offsets, u) - u
                        if a + run >= count:
                            hidden += count - a
                            break
                        hidden += run
                        a += run
                        if started:
                            for slot in range(4):
                                _advance(cursor, slot, run, run_lengths)
                        continue
                    if not started:
                        _start(cursor, line_a, line_b, a, use_r, line_runs, line_voxels, run_lengths)
                        started = True
                    stretch = min(count - a, cursor[_A_LEFT, 1], cursor[_A_RIGHT, 1])
                    stretch = min(stretch, cursor[_B_LEFT, 1], cursor[_B_RIGHT, 1])
                    shown_al = cursor[_A_LEFT, 3] == 1
                    shown_ar = use_r == 1 and cursor[_A_RIGHT, 3] == 1
                    shown_bl = use_b == 1 and cursor[_B_LEFT, 3] == 1
                    shown_br = use_b == 1 and use_r == 1 and cursor[_B_RIGHT, 3] == 1
                    if not (shown_al or shown_ar or shown_bl or shown_br):
                        transparent += stretch
                    else:
                        e_al, e_ar = cursor[_A_LEFT, 2], cursor[_A_RIGHT, 2]
                        e_bl, e_br = cursor[_B_LEFT, 2], cursor[_B_RIGHT, 2]
                        if not bounded:
                            if reach[0] <= sample_j <= reach[1] and reach[2] <= sample_k <= reach[3]:
                                tool_low, tool_high, keep_low, keep_high, removed_low, removed_high = ray_interval(
                                    tools, 0.0, sample_j, sample_k, 1.0, 0.0, 0.0, margin)
                            bounded = True
                        done = 0
                        first_i = a + fraction_i[k]
                        last_i = first_i + stretch - 1
                        if last_i < tool_low or first_i > tool_high or last_i < untested_until:
                            # The whole stretch is away from every tool, or within a clearance already found: all
                            # kept as it is (the uncut kernel's loop, with no test), or, outside a keep tool, all
                            # removed.
                            if keep_low <= first_i and last_i <= keep_high:
                                done = _composite_stretch(
                                    image, offsets, row_offsets, v, u, 0, stretch, shown_al, shown_ar,
                                    shown_bl, shown_br, w_al, w_ar, w_bl, w_br, e_al, e_ar, e_bl, e_br, voxel_classes,
                                    voxel_normals, table, shade, shading, opacity_threshold, opaque_threshold)
                            else:
                                removed += stretch
                                done = stretch
                        while done < stretch and row_offsets[u + done] == 0:
                            # Source 002, 2.5: the selection test at the sample's position in the slice.
                            sample_i = a + done + fraction_i[k]
                            if removed_low <= sample_i <= removed_high:
                                # On a chord through a remove shape: removed, like the rest of the chord.
                                step = _samples_within(removed_high - sample_i, stretch - done)
                                removed += step
                                done += step
                                continue
                            if ((sample_i < tool_low or sample_i > tool_high or sample_i < untested_until)
                                    and keep_low <= sample_i <= keep_high):
                                # Surely clear of every tool, and inside every keep tool: so are the next samples
                                # up to where that may end; composited at once, as the uncut kernel does.
                                span = stretch - done
                                if sample_i > tool_high:
                                    pass
                                elif sample_i < tool_low:
                                    span = _samples_before(tool_low - sample_i, span)
                                else:
                                    span = _samples_before(untested_until - sample_i, span)
                                span = _samples_within(keep_high - sample_i, span)
                                if sample_i < removed_low <= removed_high:
                                    span = _samples_before(removed_low - sample_i, span)
                                done = _composite_stretch(
                                    image, offsets, row_offsets, v, u, done, done + span, shown_al, shown_ar,
                                    shown_bl, shown_br, w_al, w_ar, w_bl, w_br, e_al, e_ar, e_bl, e_br,
                                    voxel_classes, voxel_normals, table, shade, shading, opacity_threshold,
                                    opaque_threshold)
                                continue
                            tested = tool_low <= sample_i <= tool_high and sample_i >= untested_until
                            if tested:
                                gval = removal(tools, sample_i, sample_j, sample_k)
                                weight_cut = visibility(tools, gval)
                                if gval >= margin:
                                    # Clear of every tool: so are the samples within the tools' clearance.
                                    untested_until = sample_i + clear_at(tools, sample_i, sample_j, sample_k,
                                                                         margin)
                            else:
                                gval = FAR
                                weight_cut = 1.0 if keep_low <= sample_i <= keep_high else 0.0
                            if weight_cut <= 0.0:
                                # Removed: so are the next samples of the line that lie within the tools' leap (the
                                # selection's empty-space skipping, as in the ray marcher; samples are one index
                                # unit apart along the line), or, outside a keep tool, up to where it begins.
                                if tested:
                                    step = _samples_before(leap_at(tools, sample_i, sample_j, sample_k),
                                                           stretch - done)
                                elif sample_i < keep_low:
                                    step = _samples_before(keep_low - sample_i, stretch - done)
                                else:
                                    step = stretch - done
                                removed += step
                                done += step
                                continue
                            cut_normal = np.int64(-1)
                            if tool_shading and gval < band:
                                cut_normal = _tool_normal_index(tools, sample_i, sample_j, sample_k, axes, spacing,
                                                                encoding, half_grid, zero_index)
                            red = green = blue = alpha = np.float32(0.0)
                            for shown, weight, e in ((shown_al, w_al, e_al + done), (shown_ar, w_ar, e_ar + done),
                                                     (shown_bl, w_bl, e_bl + done), (shown_br, w_br, e_br + done)):
                                if shown:
                                    normal = np.int64(0)
                                    if shading:
                                        normal = cut_normal if cut_normal >= 0 else np.int64(voxel_normals[e])
                                    red, green, blue, alpha = _accumulate(
                                        red, green, blue, alpha, weight, voxel_classes[e], normal, table, shade,
                                        shading)
                            if weight_cut < 1.0:
                                cut = np.float32(weight_cut)
                                red, green, blue, alpha = red * cut, green * cut, blue * cut, alpha * cut
                            _composite(image, offsets, v, u + done, red, green, blue, alpha,
                                       opacity_threshold, opaque_threshold)
                            done += 1
                        composited += done
                        stretch = done
                    if a + stretch >= count:
                        break
                    for slot in range(4):
                        _advance(cursor, slot, stretch, run_lengths)
                    a += stretch
    counts[task, 0] = composited
    counts[task, 1] = transparent
    counts[task, 2] = hidden
    counts[task, 3] = removed


def tools_for_frame(tools: ToolSet, factorization, rendered_spacing, normal_table, shading) -> tuple:
    """The tool arguments of :func:`composite_rle_cut` for one parallel frame (``tools`` in the volume frame, mm),
    made once per frame and shared by all its bands of rows: the packed tools in the standard index frame, their
    reach, the principal axis's :data:`STANDARD_AXES`, the rendered spacing and the normal table's quantisation."""
    f = factorization
    standard = tools_in_standard_frame(tools, f.principal_axis, rendered_spacing)
    if normal_table is not None:
        encoding, half_grid, zero_index = normal_table.encoding, float(normal_table.grid // 2), normal_table.zero_index
    else:
        encoding, half_grid, zero_index = np.zeros((2, 1, 1), dtype=np.int32), 0.0, 0
    packed = standard.packed()
    low, high = reach_box(packed, bounds_margin(packed, shading and standard.cut_normals))
    reach = np.array([low[1], high[1], low[2], high[2]])
    return (packed, reach, np.array(STANDARD_AXES[f.principal_axis], dtype=np.int64),
            np.asarray(rendered_spacing, dtype=np.float64), encoding, half_grid, np.uint16(zero_index))


def composite_with_tools(copy, factorization, slice_offsets, table, shade, shading, opacity_threshold, opaque, image,
                         offsets, first, last, block, counts, frame_tools: tuple) -> int:
    """Composite rows ``[first, last)`` of a parallel, unjittered frame with the tools of ``frame_tools``
    (:func:`tools_for_frame`) into ``image``; ``slice_offsets``: the factorisation's ``slice_offsets()``; ``counts``
    ``(tasks, 3)`` as the uncut kernel fills it. Returns the samples the tools removed."""
    f = factorization
    pixel_i, pixel_j, fraction_i, fraction_j = slice_offsets
    counts4 = np.zeros((counts.shape[0], 4), dtype=np.int64)
    composite_rle_cut(copy.run_lengths, copy.classes, copy.normals, copy.line_runs, copy.line_voxels, copy.shape[1],
                      copy.shape[2], f.slice_order, pixel_i, pixel_j, fraction_i, fraction_j, table, shade, shading,
                      opacity_threshold, opaque, image, offsets, first, last, block, counts4, *frame_tools)
    counts[:] = counts4[:, :3]
    return int(counts4[:, 3].sum())
