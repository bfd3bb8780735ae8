"""numba kernels of texture slicing: filling slice textures, and compositing them per pixel (the float path).

See :mod:`algorithms.rendering.texture_slicing` for the method; textures hold premultiplied RGBA, texel rows along
``v``, and are laid out as :class:`~.textures.TextureChunk` describes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...common.cutaway import cut_band, cut_normals_on, removal, removal_normal, tool_count, visibility
from ...common.pixel_rays import pixel_ray
from ...common.sampling import gradient, jitter_offset, sample_volume


@njit(cache=True, nogil=True, parallel=True)
def fill_textures(volume, inverse_spacing, box_min, box_max, origins, u_steps, v_steps, widths, starts,
                  row_slices, row_indices, table, table_min, table_scale, shading, material, eye, jitter, pass_index,
                  frame, parallel, first_columns, top_rows, depth_step, tools, out):
    """Premultiplied RGBA of the trilinear scalar at every texel centre of several slice textures.

    Texture ``m`` occupies ``out[starts[m] : starts[m] + height * width]`` (rows of ``widths[m]`` texels); the
    work items are texture rows, ``(row_slices[r], row_indices[r])``, so the threads share rows of all textures.
    Texels farther outside the box than one texel diagonal are never read by bilinear filtering inside the
    polygon; they are set to zero instead of being resampled.

    ``shading``: the colour of a texel with opacity is lit with VTK's light model (as the ray marcher's
    ``"phong"``): ``(ka + kd |n.l|) c + ks max(r.v, 0) ** p`` with ``(ka, kd, ks, p) = material``, ``n`` the
    normalised central-difference gradient of the trilinear field (source 002, 2.4.4), a headlight at ``eye``
    (volume frame, mm): ``l = v`` towards the eye, and ``r = 2 (n.l) n - l``.

    ``jitter`` (pixel-aligned view slices only: texel ``(p, q)`` of slice ``m`` lies on the ray of pixel
    ``(first_columns[m] + p, top_rows[m] - q)`` of ``frame``, :meth:`Camera.ray_frame`): each texel is sampled
    ``(j - 1/2) depth_step`` mm further along its pixel's ray, ``j`` the pixel's jitter of pass ``pass_index``,
    i.e. anywhere in its slab instead of on the slab's middle plane.

    ``tools`` (packed :class:`algorithms.common.cutaway.ToolSet`, volume frame): texels the tools remove get zero
    opacity (binary) or their weight (distance), per texel - the data volume is untouched (source 002, 2.5.1 does the
    same in its fragment shader); shaded texels within the cut band take the tool's normal.
    """
    last = table.shape[0] - 1
    sx, sy, sz = 1.0 / inverse_spacing[0], 1.0 / inverse_spacing[1], 1.0 / inverse_spacing[2]
    ambient, diffuse, specular, power = material[0], material[1], material[2], material[3]
    n_tools = tool_count(tools)
    tool_normals = n_tools > 0 and shading and cut_normals_on(tools)
    band = cut_band(tools) if n_tools > 0 else 0.0
    normal_step = 0.5 * min(sx, min(sy, sz))
    for item in prange(row_slices.shape[0]):
        m = row_slices[item]
        q = row_indices[item]
        width = widths[m]
        base = starts[m] + q * width
        margin = (math.sqrt(u_steps[m, 0] ** 2 + u_steps[m, 1] ** 2 + u_steps[m, 2] ** 2)
                  + math.sqrt(v_steps[m, 0] ** 2 + v_steps[m, 1] ** 2 + v_steps[m, 2] ** 2))
        for p in range(width):
            x = origins[m, 0] + (p + 0.5) * u_steps[m, 0] + (q + 0.5) * v_steps[m, 0]
            y = origins[m, 1] + (p + 0.5) * u_steps[m, 1] + (q + 0.5) * v_steps[m, 1]
            z = origins[m, 2] + (p + 0.5) * u_steps[m, 2] + (q + 0.5) * v_steps[m, 2]
            if (x < box_min[0] - margin or x > box_max[0] + margin or y < box_min[1] - margin
                    or y > box_max[1] + margin or z < box_min[2] - margin or z > box_max[2] + margin):
                for channel in range(4):
                    out[base + p, channel] = 0.0
                continue
            if jitter:
                col = first_columns[m] + p
                row = top_rows[m] - q
                _, _, _, dx, dy, dz = pixel_ray(frame, parallel, col, row)  # f . d = 1: one mm of depth per t
                shift = (jitter_offset(col, row, pass_index) - 0.5) * depth_step
                x += shift * dx
                y += shift * dy
                z += shift * dz
            ix, iy, iz = x * inverse_spacing[0], y * inverse_spacing[1], z * inverse_spacing[2]
            value = sample_volume(volume, ix, iy, iz)
            position = min(max((value - table_min) * table_scale, 0.0), float(last))
            entry = min(int(position), last - 1)
            fraction = position - entry
            alpha = table[entry, 3] + fraction * (table[entry + 1, 3] - table[entry, 3])
            on_cut = False
            if alpha > 0.0 and n_tools > 0:
                g = removal(tools, x, y, z)
                alpha *= visibility(tools, g)
                on_cut = tool_normals and g < band
            shade = 1.0
            highlight = 0.0
            if shading and alpha > 0.0:
                if on_cut:
                    gx, gy, gz = removal_normal(tools, x, y, z, normal_step)
                else:
                    gx, gy, gz = gradient(volume, ix, iy, iz, sx, sy, sz)
                magnitude = math.sqrt(gx * gx + gy * gy + gz * gz)
                lx, ly, lz = eye[0] - x, eye[1] - y, eye[2] - z
                distance = math.sqrt(lx * lx + ly * ly + lz * lz)
                if magnitude > 0.0 and distance > 0.0:
                    n_dot_l = (gx * lx + gy * ly + gz * lz) / (magnitude * distance)
                    r_dot_v = 2.0 * n_dot_l * n_dot_l - 1.0  # headlight: l = v
                    shade = ambient + diffuse * abs(n_dot_l)
                    if r_dot_v > 0.0 and n_dot_l != 0.0:
                        highlight = specular * r_dot_v**power
                else:
                    shade = ambient
            for channel in range(3):
                colour = table[entry, channel] + fraction * (table[entry + 1, channel] - table[entry, channel])
                out[base + p, channel] = alpha * (shade * colour + highlight)
            out[base + p, 3] = alpha


@njit(cache=True, nogil=True)
def _bilinear(textures, channel, base, width, p0, p1, q0, q1, fs, fr):
    """Bilinear interpolation of one channel of the texture at ``base`` between texels ``(q0|q1, p0|p1)``."""
    t00 = textures[base + q0 * width + p0, channel]
    t01 = textures[base + q0 * width + p1, channel]
    t10 = textures[base + q1 * width + p0, channel]
    t11 = textures[base + q1 * width + p1, channel]
    bottom = t00 + fs * (t01 - t00)
    top = t10 + fs * (t11 - t10)
    return bottom + fr * (top - bottom)


@njit(cache=True, nogil=True, parallel=True)
def composite_slices(accumulator, frame, parallel, normal, plane_offsets, box_min, box_max, tolerance, origins,
                      u_inverse, v_inverse, heights, widths, starts, textures, rows, columns, quantise):
    """Blend slice textures, in the given (back-to-front) order, over ``accumulator (H, W, 4)``:
    ``C = T + (1 - T_alpha) C`` wherever a pixel's ray meets a slice inside the box.

    ``frame`` is :meth:`algorithms.common.camera.Camera.ray_frame`. Slice ``m`` lies in the plane ``normal . x =
    plane_offsets[m]``; its texture (layout as in :func:`fill_textures`) has its texel-(0, 0) corner at ``origins[m]``,
    and ``u_inverse``/``v_inverse`` map an offset from it to texel units (``u_step / |u_step|^2``). ``rows``/
    ``columns`` bound the pixels slice ``m`` can cover. With ``quantise`` every blend is rounded to 8 bits, as a
    framebuffer stores it.
    """
    alpha_channel = np.int64(3)  # not a literal 3: numba would compile _bilinear for it as well as for int64
    for row in prange(accumulator.shape[0]):
        for m in range(plane_offsets.shape[0]):
            if row < rows[m, 0] or row >= rows[m, 1]:
                continue
            width = widths[m]
            height = heights[m]
            for col in range(columns[m, 0], columns[m, 1]):
                ox, oy, oz, dx, dy, dz = pixel_ray(frame, parallel, col, row)
                denominator = normal[0] * dx + normal[1] * dy + normal[2] * dz
                if denominator == 0.0:
                    continue
                t = (plane_offsets[m] - (normal[0] * ox + normal[1] * oy + normal[2] * oz)) / denominator
                if not parallel and t <= 0.0:
                    continue
                x = ox + t * dx
                y = oy + t * dy
                z = oz + t * dz
                if (x < box_min[0] - tolerance or x > box_max[0] + tolerance or y < box_min[1] - tolerance
                        or y > box_max[1] + tolerance or z < box_min[2] - tolerance or z > box_max[2] + tolerance):
                    continue
                rx = x - origins[m, 0]
                ry = y - origins[m, 1]
                rz = z - origins[m, 2]
                s = rx * u_inverse[m, 0] + ry * u_inverse[m, 1] + rz * u_inverse[m, 2] - 0.5
                r = rx * v_inverse[m, 0] + ry * v_inverse[m, 1] + rz * v_inverse[m, 2] - 0.5
                s = min(max(s, 0.0), width - 1.0)  # clamp to the edge texels, like GL_CLAMP_TO_EDGE
                r = min(max(r, 0.0), height - 1.0)
                p0 = min(int(s), max(width - 2, 0))
                q0 = min(int(r), max(height - 2, 0))
                p1 = min(p0 + 1, width - 1)
                q1 = min(q0 + 1, height - 1)
                fs = s - p0
                fr = r - q0
                alpha = _bilinear(textures, alpha_channel, starts[m], width, p0, p1, q0, q1, fs, fr)
                if alpha <= 0.0:
                    continue  # VTK's fragment shader discards fully transparent fragments too
                for channel in range(4):
                    if channel == 3:
                        sample = alpha
                    else:
                        sample = _bilinear(textures, channel, starts[m], width, p0, p1, q0, q1, fs, fr)
                    value = sample + (1.0 - alpha) * accumulator[row, col, channel]
                    if quantise:
                        value = math.floor(value * 255.0 + 0.5) / 255.0
                    accumulator[row, col, channel] = value
