"""Perspective shear-warp (Lacroute 1995, chapter 3, the extension source 004 names).

Perspective factorisation
-------------------------
For a camera at ``e`` (standard coordinates ``(e_i, e_j, e_k)`` of the rendered grid, ``k`` the principal axis) the
rays through the volume all start at ``e``. Project every slice from ``e`` onto the *reference plane*, the front
slice ``k_f`` (the one nearest the eye): voxel ``(i, j)`` of slice ``k`` lands at
``(e_i + s_k (i - e_i), e_j + s_k (j - e_j))`` with ``s_k = (k_f - e_k) / (k - e_k)`` in ``(0, 1]``: each slice is
*scaled* by ``s_k`` and translated (the perspective shear ``M_shear``), after which every viewing ray runs straight
along ``k`` through the intermediate image, as in the parallel case. The warp from the reference plane to the final
image is the projection of a plane through a point, a 2D *projective* map (``M_warp2D`` a homography) instead of an
affine one. The factorisation needs the eye outside the slab of slices (``e_k < 0`` or ``e_k > nk - 1``); the
principal axis is the axis of the largest component of the direction from the eye to the volume's centre (in
voxel units, as in the parallel case) among the axes along which the eye lies outside the volume.

Slices behind the front one are minified (``s_k < 1``), so intermediate pixel ``u`` samples slice ``k`` at
``i = e_i + (u + u_0 - e_i) / s_k``: the bilinear weights change from pixel to pixel, and consecutive samples of a
ray are ``|S P^-1 (d_i, d_j, 1)|`` mm apart, ``(d_i, d_j) = ((u' - e_i), (v' - e_j)) / (k_f - e_k)``, a distance
that grows towards the image corners: the opacity is corrected per pixel (the table for the smallest distance,
then ``a' = 1 - (1 - a) ** ratio`` per sample). Shading uses one light and view direction per frame, the central
ray's (a headlight), where VTK's ray caster takes them per ray.

Compositing (:func:`composite_scanlines`)
------------------------------------------
The run-length encoded copy of the principal axis is read a scanline at a time: the two scanlines feeding an
intermediate row are decoded into per-thread buffers (their stored voxels only; an empty scanline costs nothing),
the row's pixels whose sample lies inside the box are visited, runs of opaque pixels are jumped with
:func:`~.kernels.find_opaque_run_end` (early ray termination with path compression, as in the parallel kernel),
and samples are bilinear in the slice and composited front to back. Jittered frames (parallel or perspective) are
composited by :func:`.jitter.composite_jittered` with the same slice geometry.

References
----------
P. Lacroute, *Fast volume rendering using a shear-warp factorization of the viewing transformation*, PhD thesis,
Stanford University, CSL-TR-95-678, 1995, section 3.2 (the perspective factorisation). Source 004 (Tavira
Rodríguez de Liébana, 2017), chapter 4 and section 7 (perspective named as the extension).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ...common.camera import Camera
from ...common.validation import validated_image_size, validated_shape, validated_spacing
from .factorisation import STANDARD_AXES
from .kernels import _accumulate, _composite, _task_rows, add_bilinear_at_edge, find_opaque_run_end


@dataclass(frozen=True)
class PerspectiveFactorization:
    """The perspective shear-warp factorisation of one view (see the module notes).

    Attributes
    ----------
    principal_axis : int
        0, 1, 2 = x, y, z.
    permutation : ndarray (4, 4)
        Object to standard coordinates.
    eye : ndarray (3,)
        The eye in standard coordinates (voxel units of the rendered grid).
    front : int
        The reference slice ``k_f``.
    slice_order : ndarray (nk,)
        Slices front to back.
    column_offset, row_offset, inverse_scale : ndarray (nk,)
        Slice ``k`` is sampled at ``i = column_offset[k] + inverse_scale[k] u``, ``j = row_offset[k] +
        inverse_scale[k] v`` by intermediate pixel ``(u, v)``.
    warp : ndarray (3, 3)
        Homography from intermediate ``(u, v, 1)`` (pixel centres at integers) to final ``(col, row, 1)``
        (homogeneous; pixel centres at .5).
    intermediate_shape : (int, int)
        ``(height, width)`` of the intermediate image.
    sample_distance : float
        The smallest distance (mm) between consecutive samples of a ray: the opacity table's.
    distance_ratio : ndarray (height, width), float32
        Per intermediate pixel, its ray's sample distance over ``sample_distance`` (>= 1).
    """

    principal_axis: int
    permutation: np.ndarray
    eye: np.ndarray
    front: int
    slice_order: np.ndarray
    column_offset: np.ndarray
    row_offset: np.ndarray
    inverse_scale: np.ndarray
    warp: np.ndarray
    intermediate_shape: tuple[int, int]
    sample_distance: float
    distance_ratio: np.ndarray


def factorize_perspective(camera: Camera, shape, spacing, width: int, height: int) -> PerspectiveFactorization:
    """Factor the view of a perspective ``camera`` (volume frame, mm) of a ``(nz, ny, nx)`` grid (Lacroute 1995).

    Raises
    ------
    ValueError
        If the camera is parallel, or lies inside the volume's box (no slab of slices has it on one side).
    """
    if not isinstance(camera, Camera) or camera.parallel_projection:
        raise ValueError("factorize_perspective needs a perspective camera (parallel_projection=False)")
    nz, ny, nx = validated_shape(shape, min_size=2)
    spacing = np.asarray(validated_spacing(spacing), dtype=np.float64)
    width, height = validated_image_size(width, height)
    sizes = np.array([nx, ny, nz], dtype=np.float64)
    eye_object = np.asarray(camera.position, dtype=np.float64) / spacing
    towards_centre = (sizes - 1.0) / 2.0 - eye_object
    outside = [eye_object[a] < 0.0 or eye_object[a] > sizes[a] - 1.0 for a in range(3)]
    candidates = [a for a in range(3) if outside[a]]
    if not candidates:
        raise ValueError("perspective shear-warp needs the camera outside the volume's box (it lies inside): "
                         "move the camera back or use another renderer")
    principal = max(candidates, key=lambda a: abs(towards_centre[a]))
    axes = STANDARD_AXES[principal]
    permutation = np.zeros((4, 4))
    permutation[3, 3] = 1.0
    for row, axis in enumerate(axes):
        permutation[row, axis] = 1.0
    e_i, e_j, e_k = (eye_object[a] for a in axes)
    ni, nj, nk = (int(sizes[a]) for a in axes)
    front = 0 if e_k < 0 else nk - 1
    k = np.arange(nk, dtype=np.float64)
    scale = (front - e_k) / (k - e_k)
    order = np.arange(nk, dtype=np.int64) if front == 0 else np.arange(nk - 1, -1, -1, dtype=np.int64)

    def extent(e, n):
        ends = [e + scale[index] * (edge - e) for index in (0, nk - 1) for edge in (0.0, n - 1.0)]
        return math.floor(min(ends) + 1e-9), max(ends)

    u_0, u_max = extent(e_i, ni)
    v_0, v_max = extent(e_j, nj)
    cols = int(math.ceil(u_max - u_0 - 1e-9)) + 1
    rows = int(math.ceil(v_max - v_0 - 1e-9)) + 1

    # Homography: intermediate (u, v, 1) -> reference-plane point (mm, volume frame) -> camera -> pixels.
    to_object = permutation[:3, :3].T
    plane = np.column_stack([spacing * (to_object @ np.array([1.0, 0.0, 0.0])),
                             spacing * (to_object @ np.array([0.0, 1.0, 0.0])),
                             spacing * (to_object @ np.array([u_0, v_0, front], dtype=np.float64))])
    right, up, forward = camera.basis()
    rotation = np.stack([right, up, forward])
    half_w, half_h = camera.half_extents(width, height)
    intrinsics = np.array([[width / (2.0 * half_w), 0.0, width / 2.0],
                           [0.0, -height / (2.0 * half_h), height / 2.0],
                           [0.0, 0.0, 1.0]])
    warp = intrinsics @ rotation @ (plane - np.outer(np.asarray(camera.position, dtype=np.float64), [0, 0, 1]))

    # Sample distance of each intermediate pixel's ray (mm per slice).
    depth = front - e_k
    d_i = (np.arange(cols) + u_0 - e_i) / depth
    d_j = (np.arange(rows) + v_0 - e_j) / depth
    step = (to_object[:, 0][None, None, :] * d_i[None, :, None] + to_object[:, 1][None, None, :] * d_j[:, None, None]
            + to_object[:, 2][None, None, :]) * spacing
    distance = np.linalg.norm(step, axis=-1)
    smallest = float(distance.min())
    return PerspectiveFactorization(
        principal_axis=principal, permutation=permutation, eye=np.array([e_i, e_j, e_k]), front=front,
        slice_order=order, column_offset=e_i + (u_0 - e_i) / scale, row_offset=e_j + (v_0 - e_j) / scale,
        inverse_scale=1.0 / scale, warp=warp, intermediate_shape=(rows, cols), sample_distance=smallest,
        distance_ratio=np.ascontiguousarray(distance / smallest, dtype=np.float32),
    )


def parallel_scanline_offsets(slice_order, shear, translation):
    """The per-slice sampling of :func:`composite_scanlines` for a parallel factorisation: slice ``k`` lands at
    ``s k + t`` on the intermediate image, so pixel ``u`` samples it at ``i = u - (s_i k + t_i)``."""
    nk = len(slice_order)
    k = np.arange(nk, dtype=np.float64)
    return -(shear[0] * k + translation[0]), -(shear[1] * k + translation[1]), np.ones(nk)


@njit(cache=True, nogil=True, inline="always")
def _stored(line_voxels, line, total):
    """Stored (non-transparent) voxels of scanline ``line``."""
    end = line_voxels[line + 1] if line + 1 < line_voxels.shape[0] else total
    return end - line_voxels[line]


@njit(cache=True, nogil=True)
def _decode_line(run_lengths, voxel_classes, voxel_normals, shading, run, voxel, ni, classes, normals, fill):
    """Write one scanline's stored voxels into ``classes``/``normals`` (``fill`` resets them to transparent
    instead); returns the first and last stored index (``ni, -1`` when none)."""
    i = 0
    shown = False
    first, last = ni, -1
    while i < ni:
        length = np.int64(run_lengths[run])
        if shown and length > 0:
            for q in range(length):
                if fill >= 0:
                    classes[i + q] = fill
                else:
                    classes[i + q] = voxel_classes[voxel + q]
                    if shading:
                        normals[i + q] = voxel_normals[voxel + q]
            first = min(first, i)
            last = i + length - 1
            voxel += length
        i += length
        run += 1
        shown = not shown
    return first, last


@njit(cache=True, nogil=True, inline="always")
def _sample(classes_a, classes_b, normals_a, normals_b, i0, fi, fj, use_b, table, shade, shading, empty):
    """Bilinear sample of classified voxels ``i0, i0 + 1`` of scanlines A and B (B only with ``use_b``)."""
    zero = np.float32(0.0)
    red = green = blue = alpha = zero
    weights_a = ((1.0 - fi) * (1.0 - fj), fi * (1.0 - fj))
    for offset in range(2):
        entry = classes_a[i0 + offset]
        if entry != empty:
            red, green, blue, alpha = _accumulate(red, green, blue, alpha, np.float32(weights_a[offset]), entry,
                                                  normals_a[i0 + offset] if shading else 0, table, shade, shading)
        if use_b:
            entry = classes_b[i0 + offset]
            if entry != empty:
                weight = ((1.0 - fi) if offset == 0 else fi) * fj
                red, green, blue, alpha = _accumulate(red, green, blue, alpha, np.float32(weight), entry,
                                                      normals_b[i0 + offset] if shading else 0, table, shade,
                                                      shading)
    return red, green, blue, alpha


@njit(cache=True, nogil=True, inline="always")
def _over(image, offsets, v, u, red, green, blue, alpha, ratio, opacity_threshold, opaque_threshold):
    """Front-to-back over operator with the per-pixel opacity correction ``a' = 1 - (1 - a) ** ratio``."""
    if alpha <= opacity_threshold:
        return False
    if ratio != 1.0 and alpha < 1.0:
        corrected = np.float32(1.0 - (1.0 - alpha) ** ratio)
        factor = corrected / alpha
        red, green, blue, alpha = red * factor, green * factor, blue * factor, corrected
    # (threshold -1: the sample was tested above, before the correction, and is composited whatever it became)
    _composite(image, offsets, v, u, red, green, blue, alpha, -1.0, opaque_threshold)
    return True


@njit(cache=True, nogil=True, parallel=True)
def composite_scanlines(
    run_lengths, voxel_classes, voxel_normals, line_runs, line_voxels, nj, ni,
    slice_order, column_offset, row_offset, inverse_scale,
    table, shade, shading, opacity_threshold, opaque_threshold, distance_ratio, use_ratio,
    image, offsets, row_start, row_stop, block, counts,
):
    """Composite a run-length encoded copy into rows ``[row_start, row_stop)`` of the intermediate image, slices
    ``slice_order`` front to back, slice ``k`` sampled at ``(column_offset[k] + inverse_scale[k] u,
    row_offset[k] + inverse_scale[k] v)`` (see the module notes). ``table`` ends with the all-zero row of
    transparent voxels. ``counts[task]``: samples composited, pixel samples of empty scanline stretches skipped,
    samples skipped behind opaque pixels.
    """
    width = image.shape[1]
    empty = table.shape[0] - 1
    total = voxel_classes.shape[0]
    n_tasks = counts.shape[0]
    # _decode_line's flags as typed values, not literal constants: numba compiles a callee once per literal argument.
    decode, no_shading = np.int64(-1), np.bool_(False)
    for task in prange(n_tasks):
        classes_a = np.full(ni, empty, dtype=np.int64)
        classes_b = np.full(ni, empty, dtype=np.int64)
        normals_a = np.zeros(ni, dtype=np.int64)
        normals_b = np.zeros(ni, dtype=np.int64)
        composited = transparent = hidden = 0
        for v in _task_rows(np.int64(task), n_tasks, block, row_start, row_stop):  # (int64: see _task_rows)
            row_offsets = offsets[v]
            for m in range(slice_order.shape[0]):
                k = slice_order[m]
                scale = inverse_scale[k]
                low, high = width, -1
                line_a = -1
                use_b = False
                fj = 0.0
                jj = row_offset[k] + scale * v
                if -1e-9 <= jj <= nj - 1 + 1e-9:
                    j0 = min(max(int(jj), 0), nj - 2)
                    fj = min(max(jj - j0, 0.0), 1.0)
                    line_a = k * nj + j0
                    use_b = fj > 0.0
                    stored = _stored(line_voxels, line_a, total) + (
                        _stored(line_voxels, line_a + 1, total) if use_b else 0)
                    # Pixels whose sample lies in the box.
                    box_low = max(int(math.ceil((0.0 - column_offset[k]) / scale - 1e-9)), 0)
                    box_high = min(int(math.floor((ni - 1.0 - column_offset[k]) / scale + 1e-9)), width - 1)
                    if stored == 0 or box_high < box_low:
                        transparent += max(box_high - box_low + 1, 0)
                        line_a = -1
                    else:
                        first_a, last_a = _decode_line(run_lengths, voxel_classes, voxel_normals, shading,
                                                       line_runs[line_a], line_voxels[line_a], ni, classes_a,
                                                       normals_a, decode)
                        first, last = first_a, last_a
                        if use_b:
                            first_b, last_b = _decode_line(run_lengths, voxel_classes, voxel_normals, shading,
                                                           line_runs[line_a + 1], line_voxels[line_a + 1], ni,
                                                           classes_b, normals_b, decode)
                            first, last = min(first, first_b), max(last, last_b)
                        # A sample at i touches voxels floor(i) and floor(i) + 1: only first - 1 <= i < last + 1
                        # can reach a stored one.
                        low = max(box_low, int(math.ceil((first - 1.0 - column_offset[k]) / scale - 1e-9)))
                        high = min(box_high, int(math.ceil((last + 1.0 - column_offset[k]) / scale - 1e-9)) - 1)
                        transparent += max(box_high - box_low + 1 - max(high - low + 1, 0), 0)
                u = low
                while u <= high:
                    if row_offsets[u] > 0:
                        run = find_opaque_run_end(row_offsets, u) - u
                        hidden += min(run, high - u + 1)
                        u += run
                        continue
                    position = column_offset[k] + scale * u
                    i0 = min(max(int(position), 0), ni - 2)
                    fi = min(max(position - i0, 0.0), 1.0)
                    red, green, blue, alpha = _sample(classes_a, classes_b, normals_a, normals_b, i0, fi, fj,
                                                      use_b, table, shade, shading, empty)
                    ratio = distance_ratio[v, u] if use_ratio else np.float32(1.0)
                    composited += _over(image, offsets, v, u, red, green, blue, alpha, ratio, opacity_threshold,
                                        opaque_threshold)
                    u += 1
                if line_a >= 0:  # reset the scanline buffers to transparent
                    _decode_line(run_lengths, voxel_classes, voxel_normals, no_shading, line_runs[line_a],
                                 line_voxels[line_a], ni, classes_a, normals_a, empty)
                    if use_b:
                        _decode_line(run_lengths, voxel_classes, voxel_normals, no_shading, line_runs[line_a + 1],
                                     line_voxels[line_a + 1], ni, classes_b, normals_b, empty)
        counts[task, 0] = composited
        counts[task, 1] = transparent
        counts[task, 2] = hidden


@njit(cache=True, nogil=True, parallel=True)
def warp_projective(intermediate, inverse, height, width):
    """Resample the intermediate image into the final ``(height, width, 4)`` image through the homography
    ``inverse`` (final ``(col, row, 1)``, pixel centres at .5, to intermediate ``(u, v, w)``), bilinear, zero
    outside."""
    h_in, w_in, _ = intermediate.shape
    out = np.zeros((height, width, 4), dtype=np.float32)
    for row in prange(height):
        y = row + 0.5
        for col in range(width):
            x = col + 0.5
            w = inverse[2, 0] * x + inverse[2, 1] * y + inverse[2, 2]
            if w == 0.0:
                continue
            u = (inverse[0, 0] * x + inverse[0, 1] * y + inverse[0, 2]) / w
            v = (inverse[1, 0] * x + inverse[1, 1] * y + inverse[1, 2]) / w
            if not (-1.0 < u < w_in and -1.0 < v < h_in):
                continue
            u0 = np.int64(math.floor(u))
            v0 = np.int64(math.floor(v))
            fu = np.float32(u - u0)
            fv = np.float32(v - v0)
            add_bilinear_at_edge(intermediate, u0, v0, fu, fv, out, row, col)
    return out
