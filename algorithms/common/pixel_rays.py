"""The ray through one pixel, for numba kernels that walk an image pixel by pixel.

:meth:`algorithms.common.camera.Camera.ray_frame` packs a camera into five 3-vectors (``origin0``, ``direction0``,
``d_col``, ``d_row``, ``forward``; rows going down, pixel centres at ``+ 0.5``); :func:`pixel_ray` unpacks the
ray of pixel ``(col, row)`` from them inside a kernel. The ray marcher (:mod:`algorithms.rendering.raymarch`)
normalises the direction and marches along it; texture slicing (:mod:`algorithms.rendering.texture_slicing`)
intersects it with the slice planes, for which any length of the direction will do.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True, inline="always")
def pixel_ray(frame, parallel, col, row):
    """Origin and direction of the ray through the centre of pixel ``(col, row)`` (row 0 at the top).

    Parameters
    ----------
    frame : ndarray, shape (5, 3), float64
        :meth:`Camera.ray_frame` of the camera, in the frame the kernel works in (mm).
    parallel : bool
        The camera's ``parallel_projection``: the origin moves from pixel to pixel and the direction is fixed;
        otherwise (perspective) the origin is fixed and the direction changes.
    col, row : int
        The pixel.

    Returns
    -------
    ox, oy, oz, dx, dy, dz : float
        Ray origin and direction. The direction is *not* normalised for a perspective camera: its component
        along the view direction is 1, so ``o + t d`` lies ``t`` mm in front of the camera plane.
    """
    ox, oy, oz = frame[0, 0], frame[0, 1], frame[0, 2]
    dx, dy, dz = frame[1, 0], frame[1, 1], frame[1, 2]
    shift_x = col * frame[2, 0] + row * frame[3, 0]
    shift_y = col * frame[2, 1] + row * frame[3, 1]
    shift_z = col * frame[2, 2] + row * frame[3, 2]
    if parallel:
        ox, oy, oz = ox + shift_x, oy + shift_y, oz + shift_z
    else:
        dx, dy, dz = dx + shift_x, dy + shift_y, dz + shift_z
    return ox, oy, oz, dx, dy, dz
