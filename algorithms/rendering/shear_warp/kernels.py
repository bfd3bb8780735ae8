"""numba kernels of the shear-warp renderer (:mod:`algorithms.rendering.shear_warp`).

Kept apart from the Python layer so that module reads as the algorithm. The set-up kernels (classification,
normals) take the volume as ``(nz, ny, nx)``; the encoding and compositing kernels work in *standard* order
``[k, j, i]`` of one principal axis: ``k`` the slices, ``j`` the scanlines of a slice, ``i`` the voxels of a
scanline. See :mod:`algorithms.rendering.shear_warp` for the method and the references.

Run-length encoded volume (source 004, section 5.2.2), one scanline after another:

- ``run_lengths`` (uint16): alternating runs of transparent and non-transparent voxels. Every scanline starts with
  a transparent run (of length 0 when its first voxel is visible) and its runs add up to exactly ``ni`` voxels.
  One sentinel run of length 65535 ends the array so a cursor may step past the last scanline without reading
  outside it.
- ``classes`` / ``normals`` (uint16): transfer-function entry and normal index of each *non-transparent* voxel,
  in scanline order; transparent voxels are not stored.
- ``line_runs`` / ``line_voxels`` (int64, ``nk * nj``): index of the first run and of the first stored voxel of
  scanline ``(k, j)`` at ``k * nj + j``; the entries with ``j = 0`` are the source's per-slice pointers.

Intermediate image (section 5.2.3): ``image`` (float32 ``(h, w, 4)``, premultiplied colour and opacity) and
``offsets`` (int32 ``(h, w)``): 0 for a pixel that is not opaque, otherwise the distance to a pixel further along
the same run of opaque pixels or to the first non-opaque pixel after it (union-find with path compression).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ...common.atomics import take

#: Length of the sentinel run that ends every ``run_lengths`` array.
SENTINEL_RUN = 65535

# Cursor slots over the two voxel scanlines a row of the intermediate image is resampled from: scanline A (j) and
# B (j + 1), each read at the left voxel (a) and the right voxel (a + 1) of the current sample position a.
_A_LEFT, _A_RIGHT, _B_LEFT, _B_RIGHT = 0, 1, 2, 3


# --------------------------------------------------------------------------------------------------------------
# Set-up: classification, normals, run-length encoding
# --------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, parallel=True)
def classify(volume, value_min, scale, last_entry):
    """Nearest transfer-function entry (clamped to the table) of every voxel, ``uint16 (nz, ny, nx)``."""
    nz, ny, nx = volume.shape
    classes = np.empty((nz, ny, nx), dtype=np.uint16)
    for k in prange(nz):
        for j in range(ny):
            for i in range(nx):
                position = (np.float64(volume[k, j, i]) - value_min) * scale
                if position <= 0.0:
                    classes[k, j, i] = 0
                elif position >= last_entry:
                    classes[k, j, i] = last_entry
                else:
                    classes[k, j, i] = np.uint16(np.int64(position + 0.5))
    return classes


@njit(cache=True, nogil=True, forceinline=True)
def _derivative(low_value, high_value, low, high, spacing):
    """Difference quotient between samples ``low`` and ``high`` (value per mm); 0 on a one-voxel axis."""
    if high == low:
        return 0.0
    return (np.float64(high_value) - np.float64(low_value)) / ((high - low) * spacing)


@njit(cache=True, nogil=True, parallel=True)
def normal_indices(volume, sx, sy, sz, encoding, half_grid, zero_index):
    """Quantised normal of every voxel, ``uint16 (nz, ny, nx)`` (source 004, section 5.2.7).

    The normal is the negated central-difference gradient in the volume frame (mm), normalised, so it points from
    high to low values (out of dense structures). Its ``x`` and ``y`` components pick the vertex
    ``(rint(C + C nx), rint(C + C ny))`` of the source's grid (``C = half_grid``), its ``z`` sign the hemisphere;
    ``encoding[hemisphere, vx, vy]`` is the index. A zero gradient gets ``zero_index``.
    """
    nz, ny, nx = volume.shape
    out = np.empty((nz, ny, nx), dtype=np.uint16)
    for k in prange(nz):
        for j in range(ny):
            for i in range(nx):
                i0, i1 = max(i - 1, 0), min(i + 1, nx - 1)
                j0, j1 = max(j - 1, 0), min(j + 1, ny - 1)
                k0, k1 = max(k - 1, 0), min(k + 1, nz - 1)
                gx = _derivative(volume[k, j, i0], volume[k, j, i1], i0, i1, sx)
                gy = _derivative(volume[k, j0, i], volume[k, j1, i], j0, j1, sy)
                gz = _derivative(volume[k0, j, i], volume[k1, j, i], k0, k1, sz)
                norm = np.sqrt(gx * gx + gy * gy + gz * gz)
                if norm == 0.0:
                    out[k, j, i] = zero_index
                    continue
                vx = np.int64(np.rint(half_grid - half_grid * gx / norm))
                vy = np.int64(np.rint(half_grid - half_grid * gy / norm))
                hemisphere = 0 if gz <= 0.0 else 1  # the normal -g has z >= 0 in hemisphere 0
                out[k, j, i] = encoding[hemisphere, vx, vy]
    return out


@njit(cache=True, nogil=True, parallel=True)
def copy_blocked(view, out):
    """``out[...] = view`` for a transposed (strided) ``view``, in 16^3 blocks so both sides stay in cache."""
    block = 16
    nk, nj, ni = out.shape
    for kb in prange((nk + block - 1) // block):
        for jb in range(0, nj, block):
            for ib in range(0, ni, block):
                for k in range(kb * block, min(kb * block + block, nk)):
                    for j in range(jb, min(jb + block, nj)):
                        for i in range(ib, min(ib + block, ni)):
                            out[k, j, i] = view[k, j, i]


@njit(cache=True, nogil=True, parallel=True)
def count_runs(classes, visible):
    """Runs and non-transparent voxels of every scanline of a standard-order ``(nk, nj, ni)`` class array."""
    nk, nj, ni = classes.shape
    runs = np.empty(nk * nj, dtype=np.int64)
    voxels = np.empty(nk * nj, dtype=np.int64)
    for k in prange(nk):
        for j in range(nj):
            n_runs = 1
            n_voxels = 0
            current = False  # every scanline starts with a transparent run
            for i in range(ni):
                shown = visible[classes[k, j, i]]
                if shown != current:
                    n_runs += 1
                    current = shown
                if shown:
                    n_voxels += 1
            runs[k * nj + j] = n_runs
            voxels[k * nj + j] = n_voxels
    return runs, voxels


@njit(cache=True, nogil=True, parallel=True)
def fill_runs(classes, normals, visible, line_runs, line_voxels, run_lengths, voxel_classes, voxel_normals):
    """Write the runs and the non-transparent voxels (class, and normal when ``normals`` is not empty)."""
    nk, nj, ni = classes.shape
    with_normals = normals.size > 0
    for k in prange(nk):
        for j in range(nj):
            run = line_runs[k * nj + j]
            voxel = line_voxels[k * nj + j]
            current = False
            length = 0
            for i in range(ni):
                shown = visible[classes[k, j, i]]
                if shown != current:
                    run_lengths[run] = length
                    run += 1
                    length = 0
                    current = shown
                length += 1
                if shown:
                    voxel_classes[voxel] = classes[k, j, i]
                    if with_normals:
                        voxel_normals[voxel] = normals[k, j, i]
                    voxel += 1
            run_lengths[run] = length


@njit(cache=True, nogil=True, parallel=True)
def decode_runs(run_lengths, voxel_classes, line_runs, line_voxels, nk, nj, ni, fill):
    """The dense ``(nk, nj, ni)`` class array of an encoding, ``fill`` where voxels are transparent."""
    out = np.empty((nk, nj, ni), dtype=np.uint16)
    for k in prange(nk):
        for j in range(nj):
            run = line_runs[k * nj + j]
            voxel = line_voxels[k * nj + j]
            i = 0
            shown = False
            while i < ni:
                for _ in range(run_lengths[run]):
                    if shown:
                        out[k, j, i] = voxel_classes[voxel]
                        voxel += 1
                    else:
                        out[k, j, i] = fill
                    i += 1
                run += 1
                shown = not shown
    return out


# --------------------------------------------------------------------------------------------------------------
# Compositing
# --------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def find_opaque_run_end(offsets, start):
    """"Find" on one scanline of offsets: the first non-opaque pixel at or after ``start``, with path compression.

    Follows the offsets from ``start`` to the first pixel whose offset is 0 (or to the end of the scanline,
    ``len(offsets)``), then walks the same path again and points every offset on it straight at that pixel
    (source 004, section 5.2.3, "compresion del camino", and the routine "Saltar_Tramo_de_Pixels").
    """
    width = offsets.shape[0]
    end = start
    while end < width and offsets[end] > 0:
        end += offsets[end]
    position = start
    while position < end:
        step = offsets[position]
        offsets[position] = end - position
        position += step
    return end


@njit(cache=True, nogil=True, inline="always")
def _composite(image, offsets, v, u, red, green, blue, alpha, opacity_threshold, opaque_threshold):
    """Over operator, front to back, on pixel ``(v, u)``; a pixel that becomes opaque starts a run (offset 1)."""
    if alpha > opacity_threshold:
        transparency = np.float32(1.0) - image[v, u, 3]
        image[v, u, 0] += transparency * red
        image[v, u, 1] += transparency * green
        image[v, u, 2] += transparency * blue
        accumulated = image[v, u, 3] + transparency * alpha
        image[v, u, 3] = accumulated
        if accumulated >= opaque_threshold:
            offsets[v, u] = 1


@njit(cache=True, nogil=True, inline="always")
def _accumulate(red, green, blue, alpha, weight, entry, normal, table, shade, shading):
    """Add ``weight`` times a voxel's opacity-corrected, premultiplied (and shaded) colour to a sample."""
    opacity = table[entry, 3]
    if shading:
        diffuse = shade[normal, 0]
        specular = shade[normal, 1] * opacity
        return (
            red + weight * (table[entry, 0] * diffuse + specular),
            green + weight * (table[entry, 1] * diffuse + specular),
            blue + weight * (table[entry, 2] * diffuse + specular),
            alpha + weight * opacity,
        )
    return (
        red + weight * table[entry, 0],
        green + weight * table[entry, 1],
        blue + weight * table[entry, 2],
        alpha + weight * opacity,
    )


@njit(cache=True, nogil=True, inline="always")
def _advance(cursor, slot, count, run_lengths):
    """Move a run cursor ``count`` voxels along its scanline (it then sits inside a run of non-zero length).

    ``cursor[slot]`` holds ``(run index, voxels left in the run, index of the stored voxel at the cursor (or of
    the next one in a transparent run), 1 if the run is non-transparent)``.
    """
    run = cursor[slot, 0]
    left = cursor[slot, 1]
    voxel = cursor[slot, 2]
    shown = cursor[slot, 3]
    while count >= left:
        count -= left
        voxel += left * shown
        run += 1
        left = run_lengths[run]
        shown = 1 - shown
    cursor[slot, 0] = run
    cursor[slot, 1] = left - count
    cursor[slot, 2] = voxel + count * shown
    cursor[slot, 3] = shown


@njit(cache=True, nogil=True, inline="always")
def _start(cursor, line_a, line_b, position, use_r, line_runs, line_voxels, run_lengths):
    """Place the four cursors at voxel ``position`` (the left ones) and ``position + use_r`` (the right ones) of
    scanlines ``line_a`` (A) and ``line_b`` (B). (One loop, not four calls, one per slot: numba inlines every call
    of an ``inline="always"`` helper, this one's call of :func:`_advance` included, as a copy of its code.)"""
    for slot in range(4):
        line = line_a if slot < _B_LEFT else line_b
        cursor[slot, 0] = line_runs[line]
        cursor[slot, 1] = run_lengths[line_runs[line]]
        cursor[slot, 2] = line_voxels[line]
        cursor[slot, 3] = 0
        _advance(cursor, slot, position + (use_r if slot == _A_RIGHT or slot == _B_RIGHT else 0), run_lengths)


@njit(cache=True, nogil=True, inline="always")
def _slice_row(v, k, nj, pixel_j, fraction_j):
    """First voxel scanline feeding row ``v`` in slice ``k``, or -1 when the row samples outside the box."""
    line = v - pixel_j[k]
    if line < 0 or line >= nj or (line == nj - 1 and fraction_j[k] > 0.0):
        return -1
    return line


@njit(cache=True, nogil=True)
def _task_rows(task, n_tasks, block, row_start, row_stop):
    """The rows of ``[row_start, row_stop)`` task ``task`` composites, ascending: blocks of ``block`` rows dealt
    out to the ``n_tasks`` tasks in turn, so every thread gets rows from all parts of the image.

    Callers pass ``task`` as ``np.int64(task)``: numba types a ``prange`` index as int64 when it types the kernel
    and as uint64 in the outlined parallel loop body, and would compile a callee for both."""
    rows = np.arange(row_start, row_stop)
    return rows[((rows - row_start) // block) % n_tasks == task]


@njit(cache=True, nogil=True, inline="always")
def _slice_setup(v, k, nj, ni, pixel_i, pixel_j, fraction_i, fraction_j):
    """How slice ``k`` is resampled onto row ``v``: ``(line_a, use_b, use_r, count, u0, w_al, w_ar, w_bl, w_br)``.

    ``line_a``: the first voxel scanline feeding the row (-1 when the row samples outside the box, see
    :func:`_slice_row`); ``use_b``/``use_r`` (0 or 1): whether the second scanline and the right voxel carry weight
    (without them their cursors shadow the first ones, unused); ``count``: samples per row; ``u0``: the
    intermediate pixel of voxel 0; the four bilinear weights (float32) of scanline A or B, left or right voxel.
    """
    line_a = _slice_row(v, k, nj, pixel_j, fraction_j)
    weight_b = fraction_j[k]
    weight_r = fraction_i[k]
    use_b = 1 if weight_b > 0.0 else 0
    use_r = 1 if weight_r > 0.0 else 0
    w_al = np.float32((1.0 - weight_b) * (1.0 - weight_r))
    w_ar = np.float32((1.0 - weight_b) * weight_r)
    w_bl = np.float32(weight_b * (1.0 - weight_r))
    w_br = np.float32(weight_b * weight_r)
    return line_a, use_b, use_r, ni - use_r, pixel_i[k], w_al, w_ar, w_bl, w_br


@njit(cache=True, nogil=True, inline="always")
def _composite_stretch(image, offsets, row_offsets, v, u, done, stretch, shown_al, shown_ar, shown_bl, shown_br,
                       w_al, w_ar, w_bl, w_br, e_al, e_ar, e_bl, e_br, voxel_classes, voxel_normals, table, shade,
                       shading, opacity_threshold, opaque_threshold):
    """Resample, shade and composite samples ``done .. stretch - 1`` of a stretch whose four voxel cursors stay in
    their runs (voxels ``e_* + done``), stopping at the first opaque pixel; returns how far it got."""
    while done < stretch and row_offsets[u + done] == 0:
        red = green = blue = alpha = np.float32(0.0)
        for shown, weight, e in ((shown_al, w_al, e_al + done), (shown_ar, w_ar, e_ar + done),
                                 (shown_bl, w_bl, e_bl + done), (shown_br, w_br, e_br + done)):
            if shown:
                red, green, blue, alpha = _accumulate(red, green, blue, alpha, weight, voxel_classes[e],
                                                      voxel_normals[e] if shading else 0, table, shade, shading)
        _composite(image, offsets, v, u + done, red, green, blue, alpha, opacity_threshold, opaque_threshold)
        done += 1
    return done


@njit(cache=True, nogil=True, parallel=True)
def composite_rle(
    run_lengths, voxel_classes, voxel_normals, line_runs, line_voxels, nj, ni,
    slice_order, pixel_i, pixel_j, fraction_i, fraction_j,
    table, shade, shading, opacity_threshold, opaque_threshold,
    image, offsets, row_start, row_stop, block, counts,
):
    """Composite the run-length encoded volume into rows ``[row_start, row_stop)`` of the intermediate image.

    Slices are taken front to back in ``slice_order``. Slice ``k`` lands on the intermediate image translated by
    its shear offset: pixel ``u`` of row ``v`` samples the slice at ``(i, j) = (u - pixel_i[k] + fraction_i[k],
    v - pixel_j[k] + fraction_j[k])``, i.e. it blends voxels ``a = u - pixel_i[k]`` and ``a + 1`` of scanlines
    ``jA = v - pixel_j[k]`` and ``jA + 1`` with the slice's bilinear weights. Only samples inside the rendered box
    (between the first and last voxel centres) are taken.

    Within a row, runs of opaque pixels are jumped with :func:`find_opaque_run_end` and stretches where all four
    voxel cursors are in transparent runs are skipped without touching a voxel; everything else is resampled,
    shaded through the per-view tables and composited. Rows are independent (a row of the intermediate image only
    reads voxel scanlines and writes itself), so the threads take blocks of ``block`` rows one at a time from a
    shared counter (:func:`algorithms.common.atomics.take`: a thread whose rows are busy takes fewer), each thread
    compositing every slice of its rows in front-to-back order. ``counts[task]`` receives (samples composited,
    samples skipped as transparent, samples skipped behind opaque pixels).
    """
    n_tasks = counts.shape[0]
    queue = np.zeros(1, dtype=np.int64)
    for task in prange(n_tasks):
        cursor = np.zeros((4, 4), dtype=np.int64)
        composited = 0
        transparent = 0
        hidden = 0
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
                    line_a += k * nj
                    line_b = line_a + use_b
                    started = False
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
                        # The stretch over which every cursor stays in its current run.
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
                            done = _composite_stretch(
                                image, offsets, row_offsets, v, u, 0, stretch, shown_al, shown_ar, shown_bl,
                                shown_br, w_al, w_ar, w_bl, w_br, e_al, e_ar, e_bl, e_br, voxel_classes, voxel_normals,
                                table, shade, shading, opacity_threshold, opaque_threshold)
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


@njit(cache=True, nogil=True, parallel=True)
def composite_dense(
    classes, normals, slice_order, pixel_i, pixel_j, fraction_i, fraction_j,
    table, shade, shading, opacity_threshold, opaque_threshold,
    image, offsets, row_start, row_stop, block, counts,
):
    """Brute-force counterpart of :func:`composite_rle`: visits every voxel of a dense ``(nk, nj, ni)`` class array.

    Transparent voxels hold the class of an all-zero table row, so the image equals the run-length encoded one;
    runs of opaque pixels are still jumped (early ray termination), only the volume's run-length encoding is
    missing. ``counts[task]`` as in :func:`composite_rle` (no transparent skipping).
    """
    nk, nj, ni = classes.shape
    n_tasks = counts.shape[0]
    for task in prange(n_tasks):
        composited = 0
        hidden = 0
        for v in _task_rows(np.int64(task), n_tasks, block, row_start, row_stop):  # (int64: see _task_rows)
            row_offsets = offsets[v]
            for k in slice_order:
                ja, use_b, use_r, count, u0, w_al, w_ar, w_bl, w_br = _slice_setup(
                    v, k, nj, ni, pixel_i, pixel_j, fraction_i, fraction_j)
                if ja < 0:
                    continue
                jb = ja + use_b
                a = 0
                while a < count:
                    if row_offsets[u0 + a] > 0:
                        run = find_opaque_run_end(row_offsets, u0 + a) - (u0 + a)
                        hidden += min(run, count - a)
                        a += run
                        continue
                    ar = a + use_r
                    zero = np.float32(0.0)
                    red, green, blue, alpha = _accumulate(
                        zero, zero, zero, zero, w_al, classes[k, ja, a], normals[k, ja, a] if shading else 0,
                        table, shade, shading)
                    if use_r:
                        red, green, blue, alpha = _accumulate(
                            red, green, blue, alpha, w_ar, classes[k, ja, ar], normals[k, ja, ar] if shading else 0,
                            table, shade, shading)
                    if use_b:
                        red, green, blue, alpha = _accumulate(
                            red, green, blue, alpha, w_bl, classes[k, jb, a], normals[k, jb, a] if shading else 0,
                            table, shade, shading)
                        if use_r:
                            red, green, blue, alpha = _accumulate(
                                red, green, blue, alpha, w_br, classes[k, jb, ar],
                                normals[k, jb, ar] if shading else 0, table, shade, shading)
                    _composite(image, offsets, v, u0 + a, red, green, blue, alpha, opacity_threshold,
                               opaque_threshold)
                    composited += 1
                    a += 1
        counts[task, 0] = composited
        counts[task, 1] = 0
        counts[task, 2] = hidden


# --------------------------------------------------------------------------------------------------------------
# Warp
# --------------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, forceinline=True)
def _inside_columns(slope, intercept, low, high, width):
    """Columns ``x`` in ``[0, width)`` with ``low < slope * (x + 0.5) + intercept < high``, as ``[first, stop)``.

    Widened by one column on each side against rounding; the caller checks every tap anyway.
    """
    if slope == 0.0:
        return (0, width) if low < intercept < high else (0, 0)
    a = (low - intercept) / slope - 0.5
    b = (high - intercept) / slope - 0.5
    if slope < 0.0:
        a, b = b, a
    # Clamp in floating point first: a tiny slope puts a and b far beyond the int64 range.
    first = np.int64(min(max(np.floor(a), 0.0), width))
    stop = np.int64(min(max(np.ceil(b) + 1.0, 0.0), width))
    return first, max(first, stop)


@njit(cache=True, nogil=True, inline="always")
def add_bilinear_at_edge(intermediate, u0, v0, fu, fv, out, row, col):
    """Add to ``out[row, col]`` the bilinear sample of ``intermediate`` in the cell with lower corner ``(u0, v0)``
    at fractions ``(fu, fv)`` (float32), counting the corners outside the image as zero: the warps' sample where
    the cell leaves the intermediate image."""
    h_in, w_in, _ = intermediate.shape
    for dv in range(2):
        vv = v0 + dv
        if vv < 0 or vv >= h_in:
            continue
        wv = fv if dv else np.float32(1.0) - fv
        for du in range(2):
            uu = u0 + du
            if uu < 0 or uu >= w_in:
                continue
            weight = wv * (fu if du else np.float32(1.0) - fu)
            for c in range(4):
                out[row, col, c] += weight * intermediate[vv, uu, c]


@njit(cache=True, nogil=True, parallel=True)
def warp_bilinear(intermediate, inverse, height, width):
    """Resample the intermediate image into the final ``(height, width, 4)`` image (row 0 at the top).

    ``inverse`` (3x3) maps final pixel coordinates ``(col, row, 1)`` (pixel centres at .5) to intermediate
    coordinates ``(u, v, 1)`` (pixel centres at integers); samples are bilinear, zero outside the image. Per row,
    only the columns whose sample can touch the intermediate image are visited (the affine map makes that an
    interval).
    """
    h_in, w_in, _ = intermediate.shape
    out = np.zeros((height, width, 4), dtype=np.float32)
    du, dv = inverse[0, 0], inverse[1, 0]
    for row in prange(height):
        y = row + 0.5
        u_row = inverse[0, 1] * y + inverse[0, 2]
        v_row = inverse[1, 1] * y + inverse[1, 2]
        first_u, stop_u = _inside_columns(du, u_row, -1.0, np.float64(w_in), width)
        first_v, stop_v = _inside_columns(dv, v_row, -1.0, np.float64(h_in), width)
        for col in range(max(first_u, first_v), min(stop_u, stop_v)):
            x = col + 0.5
            u = du * x + u_row
            v = dv * x + v_row
            u0 = np.int64(np.floor(u))
            v0 = np.int64(np.floor(v))
            fu = np.float32(u - u0)
            fv = np.float32(v - v0)
            if u0 >= 0 and v0 >= 0 and u0 + 1 < w_in and v0 + 1 < h_in:
                w00 = (np.float32(1.0) - fu) * (np.float32(1.0) - fv)
                w01 = fu * (np.float32(1.0) - fv)
                w10 = (np.float32(1.0) - fu) * fv
                w11 = fu * fv
                for c in range(4):
                    out[row, col, c] = (w00 * intermediate[v0, u0, c] + w01 * intermediate[v0, u0 + 1, c]
                                        + w10 * intermediate[v0 + 1, u0, c] + w11 * intermediate[v0 + 1, u0 + 1, c])
                continue
            add_bilinear_at_edge(intermediate, u0, v0, fu, fv, out, row, col)
    return out
