"""numba kernels of the ray-marching volume renderer (see :mod:`algorithms.rendering.raymarch.core` for the method).

Coordinates inside the kernels are *index* coordinates: voxel ``(i, j, k)`` sits at ``(x, y, z) = (i, j, k)``; a
ray is ``p(t) = o + t * d`` with ``t`` in millimetres along the unit world direction, so its index-space
direction is ``d / spacing``. The volume array is ``(nz, ny, nx)`` float32, indexed ``[k, j, i]``.

Per-ray sampling (the rule of VTK's GPU ray caster): the ray enters the box of voxel centres
``[0, nx-1] x [0, ny-1] x [0, nz-1]`` at ``t_in`` and leaves it at ``t_out``; samples are taken at
``t_in + (k - 1 + j) * d`` for ``k = 1 .. n`` while inside the box, with ``d`` the sample distance (mm) and ``j``
the pixel's jitter in [0, 1) (:func:`algorithms.common.sampling.jitter_offset`), or ``j = 1`` without jittering:
then the first sample lies one sample distance inside the box and the last partial distance is dropped, exactly
as VTK does with ``UseJittering`` off (with it on, VTK offsets by a noise texture value in [0, 1) too).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...common.cutaway import (
    clear_at,
    cut_band,
    cut_normals_on,
    leap_at,
    removal,
    removal_normal,
    tool_count,
    visibility,
)
from ...common.cutaway_bounds import bounds_margin, ray_interval
from ...common.pixel_rays import pixel_ray
from ...common.sampling import cell_of, gradient, jitter_offset, sample_volume, second_jitter_offset, trilinear

#: Lighting model codes shared with :mod:`algorithms.rendering.raymarch.core`.
EMISSION = 0
PHONG = 1
SCATTER = 2

# A sample counts as inside a box when it lies less than this fraction of a sample distance beyond a face: absorbs
# the rounding of t_in + k * d so that a box exactly n sample distances deep gets n samples.
_SAMPLE_EPSILON = 1e-6


@njit(cache=True, nogil=True, parallel=True)
def brick_value_ranges(volume, brick_size):
    """Smallest and largest voxel value of each brick, two ``(nbz, nby, nbx)`` float32 arrays.

    Brick ``(bk, bj, bi)`` holds the cells (trilinear interpolation cells, between voxel centres) whose lower
    corner index lies in ``[b * B, (b + 1) * B)`` per axis, so its voxels are ``b * B .. min((b + 1) * B, n - 1)``
    inclusive: neighbouring bricks share a layer of voxels, and every value trilinear interpolation can produce
    inside a brick lies within the brick's range.
    """
    nz, ny, nx = volume.shape
    nbz = (nz - 2) // brick_size + 1
    nby = (ny - 2) // brick_size + 1
    nbx = (nx - 2) // brick_size + 1
    low = np.empty((nbz, nby, nbx), dtype=np.float32)
    high = np.empty((nbz, nby, nbx), dtype=np.float32)
    for bk in prange(nbz):
        k0 = bk * brick_size
        k1 = min(k0 + brick_size, nz - 1)
        for bj in range(nby):
            j0 = bj * brick_size
            j1 = min(j0 + brick_size, ny - 1)
            for bi in range(nbx):
                i0 = bi * brick_size
                i1 = min(i0 + brick_size, nx - 1)
                lo = volume[k0, j0, i0]
                hi = lo
                for k in range(k0, k1 + 1):
                    for j in range(j0, j1 + 1):
                        for i in range(i0, i1 + 1):
                            value = volume[k, j, i]
                            if value < lo:
                                lo = value
                            elif value > hi:
                                hi = value
                low[bk, bj, bi] = lo
                high[bk, bj, bi] = hi
    return low, high


@njit(cache=True, nogil=True, parallel=True)
def gradients_at(volume, points, spacing):
    """:func:`gradient` at many index-space points ``(n, 3)`` (x, y, z order); returns ``(n, 3)`` float64."""
    out = np.empty((points.shape[0], 3), dtype=np.float64)
    for p in prange(points.shape[0]):
        gx, gy, gz = gradient(volume, points[p, 0], points[p, 1], points[p, 2], spacing[0], spacing[1], spacing[2])
        out[p, 0] = gx
        out[p, 1] = gy
        out[p, 2] = gz
    return out


@njit(cache=True, nogil=True)
def _slab(ox, oy, oz, dx, dy, dz, low_x, low_y, low_z, high_x, high_y, high_z):
    """Entry and exit ``t`` of the ray ``o + t * d`` with the box ``[low, high]`` (exit < entry: a miss)."""
    t_near = -np.inf
    t_far = np.inf
    for o, d, low, high in ((ox, dx, low_x, high_x), (oy, dy, low_y, high_y), (oz, dz, low_z, high_z)):
        if d != 0.0:
            t0 = (low - o) / d
            t1 = (high - o) / d
            if t0 > t1:
                t0, t1 = t1, t0
            t_near = max(t_near, t0)
            t_far = min(t_far, t1)
        elif o < low or o > high:
            return np.inf, -np.inf
    return t_near, t_far


@njit(cache=True, nogil=True)
def _lookup_alpha(table, position):
    """Opacity at a (clamped) fractional table position, linear between entries; also the entry and fraction."""
    last = table.shape[0] - 1
    if position <= 0.0:
        return table[0, 3], 0, 0.0
    if position >= last:
        return table[last, 3], last - 1, 1.0
    entry = int(position)
    fraction = position - entry
    return table[entry, 3] + fraction * (table[entry + 1, 3] - table[entry, 3]), entry, fraction


@njit(cache=True, nogil=True)
def _lookup_extinction(extinction, position):
    """Extinction (per mm) at a (clamped) fractional table position, linear between entries."""
    last = extinction.shape[0] - 1
    if position <= 0.0:
        return extinction[0]
    if position >= last:
        return extinction[last]
    entry = int(position)
    return extinction[entry] + (position - entry) * (extinction[entry + 1] - extinction[entry])


@njit(cache=True, nogil=True)
def _light_transmittance(volume, x, y, z, lx, ly, lz, extinction, table_min, table_scale, light_samples, tight,
                         offset, tools, sx, sy, sz):
    """Beer-Lambert transmittance from index point ``(x, y, z)`` towards the light, up to where the path leaves
    the index box ``tight`` (``(low_x, low_y, low_z, high_x, high_y, high_z)``: the box of voxel centres, or the
    box around the bricks that can hold any opacity, outside which the extinction is exactly zero).

    ``(lx, ly, lz)`` is the index-space direction towards the light (unit world direction / spacing). The segment
    is split into ``light_samples`` equal parts sampled at ``offset`` (0.5: their midpoints; the pixel's jitter
    otherwise), a Riemann sum of source 001's integral: ``T = exp(-delta * sum(sigma_j))`` with ``sigma`` the
    extinction per mm. Cut-away ``tools`` (:mod:`algorithms.common.cutaway`) remove absorbing matter on the way
    too (``sx, sy, sz``: the spacing, to evaluate them in mm).
    """
    t_near, t_far = _slab(x, y, z, lx, ly, lz, tight[0], tight[1], tight[2], tight[3], tight[4], tight[5])
    if not t_far > max(t_near, 0.0):
        return 1.0
    t_start = max(t_near, 0.0)
    delta = (t_far - t_start) / light_samples
    optical_depth = 0.0
    for j in range(light_samples):
        t = t_start + (j + offset) * delta
        px, py, pz = x + t * lx, y + t * ly, z + t * lz
        value = sample_volume(volume, px, py, pz)
        sigma = _lookup_extinction(extinction, (value - table_min) * table_scale)
        if sigma > 0.0 and tool_count(tools) > 0:
            sigma *= visibility(tools, removal(tools, px * sx, py * sy, pz * sz))
        optical_depth += sigma
    return math.exp(-delta * optical_depth)


@njit(cache=True, nogil=True)
def _sample_range(ox, oy, oz, dx, dy, dz, nx, ny, nz, sample_distance, skipping, any_visible, tight_low, tight_high,
                  offset):
    """Which samples of a ray to march: ``(hit, t_0, first, last, n_samples)``.

    The ray ``o + t * d`` (index space, ``t`` in mm) enters the box of voxel centres at ``t_in`` and samples at
    ``t_0 + k * sample_distance`` for ``k = 1 .. n_samples``, ``t_0 = t_in + offset * sample_distance`` with
    ``offset = j - 1`` in [-1, 0] (the jitter; 0 without it). ``first .. last`` is the part that can hold visible
    samples (all of it without empty-space skipping, else the part inside ``tight_low .. tight_high``, the index box
    around the non-empty bricks, given as two ``(x, y, z)`` tuples; ``first > last`` when none can).
    """
    t_in, t_out = _slab(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, nx - 1.0, ny - 1.0, nz - 1.0)
    t_in = max(t_in, 0.0)
    if not t_out >= t_in:
        return False, 0.0, 1, 0, 0
    t_0 = t_in + offset * sample_distance
    n_samples = int(math.floor((t_out - t_0) / sample_distance + _SAMPLE_EPSILON))
    first, last = 1, n_samples
    if skipping:
        if not any_visible:
            return True, t_0, 1, 0, n_samples
        # Only the box around the non-empty bricks can hold visible samples; the sample grid stays the same.
        t_low, t_high = _slab(ox, oy, oz, dx, dy, dz, *tight_low, *tight_high)
        if not t_high >= t_low:
            return True, t_0, 1, 0, n_samples
        first = max(first, int(math.ceil((t_low - t_0) / sample_distance - _SAMPLE_EPSILON)))
        last = min(last, int(math.floor((t_high - t_0) / sample_distance + _SAMPLE_EPSILON)))
    return True, t_0, first, last, n_samples


@njit(cache=True, nogil=True)
def _light_vectors(dx, dy, dz, headlight, light_x, light_y, light_z, phase_g, parallel, ex, ey, ez, px, py, pz):
    """Unit world vectors towards the light (l) and towards the viewer (v), and the phase value.

    ``(dx, dy, dz)`` is the unit world ray direction. As in VTK's GPU ray caster, the viewer and a headlight sit at
    the camera position ``e`` and both directions are taken once per ray, from its box entry point ``p``:
    ``l = v = (e - p) / |e - p|``, which is ``-d`` for a perspective camera and leans towards the camera position
    off the image centre for a parallel one. A directional light gives ``l`` itself and ``v = -d``. The
    Henyey-Greenstein phase function is normalised so that isotropic scattering gives 1; the scattering angle lies
    between the light's direction of travel (-l) and the direction towards the camera (v).
    """
    vx, vy, vz = -dx, -dy, -dz
    if headlight:
        if parallel:
            wx, wy, wz = ex - px, ey - py, ez - pz
            norm = math.sqrt(wx * wx + wy * wy + wz * wz)
            if norm > 0.0:
                vx, vy, vz = wx / norm, wy / norm, wz / norm
        lx, ly, lz = vx, vy, vz
    else:
        lx, ly, lz = light_x, light_y, light_z
    cos_theta = -(lx * vx + ly * vy + lz * vz)
    g2 = phase_g * phase_g
    phase = (1.0 - g2) / (1.0 + g2 - 2.0 * phase_g * cos_theta) ** 1.5
    return lx, ly, lz, vx, vy, vz, phase


@njit(cache=True, nogil=True)
def _render_row(
    row, frame, parallel_projection, volume, spacing, sample_distance, table, table_min, table_scale, extinction,
    empty_reach, brick_of_cell, brick_size, tight, any_visible, skipping, lighting, light, headlight, ambient, diffuse,
    specular, specular_power, gradient_threshold, termination, light_samples, albedo, phase_g, jitter, pass_index,
    eye, light_box, tools, image, counts,
):
    """Render one image row (see :func:`render_rows`).

    The per-ray work is written out here rather than in a function called per pixel: numba reference-counts the
    arrays handed to a call, and those atomic updates on shared arrays would cost more than a missed ray.
    """
    nz, ny, nx = volume.shape
    width = image.shape[1]
    sx, sy, sz = spacing[0], spacing[1], spacing[2]
    inverse_distance = 1.0 / sample_distance
    tight_low, tight_high = (tight[0], tight[1], tight[2]), (tight[3], tight[4], tight[5])
    light_x, light_y, light_z = light[0], light[1], light[2]
    ex, ey, ez = eye[0], eye[1], eye[2]
    n_tools = tool_count(tools)
    tool_normals = n_tools > 0 and cut_normals_on(tools) and lighting == PHONG
    band = cut_band(tools) if n_tools > 0 else 0.0
    margin = bounds_margin(tools, tool_normals) if n_tools > 0 else 0.0
    normal_step = 0.5 * min(sx, min(sy, sz))
    hits = evaluated_total = skipped_total = stopped = 0
    for col in range(width):
        # The ray of pixel (col, row), in the volume frame (mm); then in index space, so t stays in mm.
        ox, oy, oz, dx, dy, dz = pixel_ray(frame, parallel_projection, col, row)
        norm = math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx / norm, dy / norm, dz / norm
        ox, oy, oz = ox / sx, oy / sy, oz / sz
        ix, iy, iz = dx / sx, dy / sy, dz / sz

        red = green = blue = alpha = 0.0
        j = jitter_offset(col, row, pass_index) if jitter else 1.0
        hit, t_in, first, last, n_samples = _sample_range(
            ox, oy, oz, ix, iy, iz, nx, ny, nz, sample_distance, skipping, any_visible, tight_low, tight_high, j - 1.0
        )
        tool_low, tool_high = np.inf, -np.inf
        removed_low, removed_high = 1.0, 0.0
        untested_until = -np.inf  # samples before this (mm along the ray) are surely clear of every tool
        if hit and n_tools > 0:
            # Where along the ray the tools can matter (tested there only), the part that keep tools keep, and a
            # chord through a remove tool where every sample is removed (jumped without a look-up).
            tool_low, tool_high, keep_low, keep_high, removed_low, removed_high = ray_interval(
                tools, ox * sx, oy * sy, oz * sz, dx, dy, dz, margin)
            if keep_low > -np.inf:
                first = max(first, int(math.ceil((keep_low - t_in) * inverse_distance - _SAMPLE_EPSILON)))
            if keep_high < np.inf:
                last = min(last, int(math.floor((keep_high - t_in) * inverse_distance + _SAMPLE_EPSILON)))
            hit = first <= last
        if hit:
            # The box entry point in world mm (t_in + d is the first unjittered sample, t_in the entry).
            t_entry = t_in + (1.0 - j) * sample_distance
            lx, ly, lz, vx, vy, vz, phase = _light_vectors(
                dx, dy, dz, headlight, light_x, light_y, light_z, phase_g, parallel_projection, ex, ey, ez,
                (ox + t_entry * ix) * sx, (oy + t_entry * iy) * sy, (oz + t_entry * iz) * sz)
            light_offset = second_jitter_offset(col, row, pass_index) if jitter else 0.5
            l_dot_v = lx * vx + ly * vy + lz * vz
            # Brick leaping: per axis, the reciprocal direction and which face of a cube of bricks the ray leaves by.
            inverse_x = 1.0 / ix if ix != 0.0 else 0.0
            inverse_y = 1.0 / iy if iy != 0.0 else 0.0
            inverse_z = 1.0 / iz if iz != 0.0 else 0.0
            ahead_x, ahead_y, ahead_z = ix > 0.0, iy > 0.0, iz > 0.0
            evaluated = 0
            skipped = first - 1 if skipping else 0
            terminated = False
            k = first
            while k <= last:
                t = t_in + k * sample_distance
                if removed_low <= t <= removed_high:
                    # (Compared before the conversion: a half-space's chord never ends.)
                    reach = (removed_high - t_in) * inverse_distance
                    following = last + 1 if not reach < last else max(int(math.floor(reach)) + 1, k + 1)
                    skipped += following - k
                    k = following
                    continue
                x = ox + t * ix
                y = oy + t * iy
                z = oz + t * iz
                i0, fx = cell_of(x, nx)
                j0, fy = cell_of(y, ny)
                k0, fz = cell_of(z, nz)
                if skipping:
                    bi, bj, bk = brick_of_cell[i0], brick_of_cell[j0], brick_of_cell[k0]
                    reach = empty_reach[bk, bj, bi]
                    if reach > 0:
                        # Every brick within Chebyshev distance reach - 1 is empty: leap out of the cube of bricks
                        # b - reach + 1 .. b + reach - 1 to the first sample of the same grid not clearly inside it.
                        t_exit = np.inf
                        if inverse_x != 0.0:
                            face = bi + reach if ahead_x else bi - reach + 1
                            t_exit = min(t_exit, (face * brick_size - ox) * inverse_x)
                        if inverse_y != 0.0:
                            face = bj + reach if ahead_y else bj - reach + 1
                            t_exit = min(t_exit, (face * brick_size - oy) * inverse_y)
                        if inverse_z != 0.0:
                            face = bk + reach if ahead_z else bk - reach + 1
                            t_exit = min(t_exit, (face * brick_size - oz) * inverse_z)
                        following = k + 1
                        if t_exit < np.inf:
                            following = max(following,
                                            int(math.ceil((t_exit - t_in) * inverse_distance - _SAMPLE_EPSILON)))
                        following = min(following, last + 1)
                        skipped += following - k
                        k = following
                        continue
                value = trilinear(volume, i0, j0, k0, fx, fy, fz)
                evaluated += 1
                a, entry, fraction = _lookup_alpha(table, (value - table_min) * table_scale)
                on_cut = False
                if a > 0.0 and tool_low <= t <= tool_high and t >= untested_until:
                    # Source 002, 2.5: the selection test before the sample's colour (binary), or the smooth
                    # weight of the distance difference (3.3.1); the data volume is never changed.
                    g = removal(tools, x * sx, y * sy, z * sz)
                    a *= visibility(tools, g)
                    on_cut = tool_normals and g < band
                    if a == 0.0:
                        # Inside the removed region: leap over the samples that are surely removed too (the
                        # selection's own empty-space skipping: shapes' distances, grid tools' depth tables; strict,
                        # so none that could be kept is skipped).
                        reach = leap_at(tools, x * sx, y * sy, z * sz) * inverse_distance
                        leap = int(math.ceil(reach)) - 1 if reach <= last - k else last - k
                        if leap > 0:
                            skipped += leap
                            k += leap + 1
                            continue
                    elif g >= margin:
                        # Clear of every tool (kept, not on the cut): so are the samples within the tools'
                        # clearance, which need no test (shapes' distances, grid tools' clearance tables).
                        untested_until = t + clear_at(tools, x * sx, y * sy, z * sz, margin)
                if a > 0.0:
                    r = table[entry, 0] + fraction * (table[entry + 1, 0] - table[entry, 0])
                    g = table[entry, 1] + fraction * (table[entry + 1, 1] - table[entry, 1])
                    b = table[entry, 2] + fraction * (table[entry + 1, 2] - table[entry, 2])
                    if lighting == PHONG:
                        if on_cut:
                            # The cut face is shaded with the tool's normal, not the data gradient whose stencil
                            # reaches into the removed region.
                            gx, gy, gz = removal_normal(tools, x * sx, y * sy, z * sz, normal_step)
                        else:
                            gx, gy, gz = gradient(volume, x, y, z, sx, sy, sz)
                        magnitude = math.sqrt(gx * gx + gy * gy + gz * gz)
                        if magnitude > 0.0:
                            weight = (1.0 if gradient_threshold <= 0.0 or on_cut
                                      else min(1.0, magnitude / gradient_threshold))
                            # VTK's light model: two-sided diffuse |n.l|; Phong's reflection vector r = 2 (n.l) n - l
                            # for the specular term max(r.v, 0) ** s, a white highlight (does not depend on the
                            # sign of n, so the gradient's own direction will do).
                            n_dot_l = (gx * lx + gy * ly + gz * lz) / magnitude
                            n_dot_v = (gx * vx + gy * vy + gz * vz) / magnitude
                            r_dot_v = 2.0 * n_dot_l * n_dot_v - l_dot_v
                            shade = ambient + diffuse * abs(n_dot_l)
                            highlight = 0.0
                            if r_dot_v > 0.0 and n_dot_l != 0.0:
                                highlight = specular * r_dot_v**specular_power
                            r = (1.0 - weight) * r + weight * (shade * r + highlight)
                            g = (1.0 - weight) * g + weight * (shade * g + highlight)
                            b = (1.0 - weight) * b + weight * (shade * b + highlight)
                        elif gradient_threshold <= 0.0:
                            # No gradient, no direction: VTK lights such a sample by the ambient term alone.
                            r *= ambient
                            g *= ambient
                            b *= ambient
                    elif lighting == SCATTER:
                        reaching = _light_transmittance(
                            volume, x, y, z, lx / sx, ly / sy, lz / sz, extinction, table_min, table_scale,
                            light_samples, light_box, light_offset, tools, sx, sy, sz,
                        )
                        scattered = albedo * phase * reaching
                        r *= scattered
                        g *= scattered
                        b *= scattered
                    weight = (1.0 - alpha) * a
                    red += weight * r
                    green += weight * g
                    blue += weight * b
                    alpha += weight
                    if alpha >= termination:
                        terminated = True
                        break
                k += 1
            if skipping and not terminated:
                skipped += n_samples - last
            hits += 1
            evaluated_total += evaluated
            skipped_total += skipped
            stopped += terminated
        image[row, col, 0] = red
        image[row, col, 1] = green
        image[row, col, 2] = blue
        image[row, col, 3] = alpha
    counts[row, 0] = hits
    counts[row, 1] = evaluated_total
    counts[row, 2] = skipped_total
    counts[row, 3] = stopped


@njit(cache=True, nogil=True, parallel=True)
def render_rows(
    rows, frame, parallel_projection, volume, spacing, sample_distance, table, table_min, table_scale, extinction,
    empty_reach, brick_of_cell, brick_size, tight, any_visible, skipping, lighting, light, headlight, ambient, diffuse,
    specular, specular_power, gradient_threshold, termination, light_samples, albedo, phase_g, jitter, pass_index,
    eye, light_box, tools, image, counts,
):
    """Render the image rows listed in ``rows`` into ``image`` ``(h, w, 4)`` (premultiplied RGBA), in parallel.

    ``frame`` is :meth:`algorithms.common.camera.Camera.ray_frame` in the volume frame (mm). ``empty_reach[bk, bj, bi]``
    is 0 for a non-empty brick, else the Chebyshev distance (in bricks) to the nearest non-empty one;
    ``brick_of_cell[c]`` is ``c // brick_size`` (looked up: no integer division per sample). ``tight`` is the
    index box ``(low_x, low_y, low_z, high_x, high_y, high_z)`` around the non-empty bricks; ``light`` the unit
    volume-frame vector towards the light (ignored for a headlight), ``eye`` the camera position (volume frame,
    mm), ``light_box`` the index box the light march stays in, ``tools`` the packed cut-away tools
    (:meth:`algorithms.common.cutaway.ToolSet.packed`, renderer frame). ``jitter`` shifts each ray's samples by its pixel's
    :func:`~algorithms.common.sampling.jitter_offset` of pass ``pass_index``. ``counts[row]`` receives (rays hitting the
    box, samples evaluated, samples skipped, rays stopped by early termination).
    """
    for r in prange(rows.shape[0]):
        _render_row(
            rows[r], frame, parallel_projection, volume, spacing, sample_distance, table, table_min, table_scale,
            extinction, empty_reach, brick_of_cell, brick_size, tight, any_visible, skipping, lighting, light,
            headlight, ambient, diffuse, specular, specular_power, gradient_threshold, termination, light_samples,
            albedo, phase_g, jitter, pass_index, eye, light_box, tools, image, counts,
        )
