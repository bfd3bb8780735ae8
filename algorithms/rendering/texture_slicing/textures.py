"""The texel grids of one frame of texture slicing: which pixels each slice can cover and where its texels lie.

A :class:`SliceLayout` holds, for every slice of a frame, its pixel range and the grid of its 2D texture (origin,
one texel along ``u`` and ``v``, shape); :class:`SliceTexture` is one filled texture, :class:`TextureChunk` the
textures of consecutive slices in one flat array, as the kernels fill them. See
:mod:`algorithms.rendering.texture_slicing` for the method.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...common.camera import Camera
from .geometry import MAX_POLYGON_VERTICES, SlicePolygons

#: Texels resampled per kernel launch (a chunk of slices; 4 M texels of float32 RGBA are 64 MB).
CHUNK_TEXELS = 1 << 22


@dataclass(frozen=True)
class SliceTexture:
    """The 2D texture of one slice, in the slice's plane frame.

    Texel ``(p, q)`` (column ``p``, row ``q``) is centred at ``origin + (p + 0.5) u_step + (q + 0.5) v_step``, so
    texture coordinates ``(s, t)`` in [0, 1] span ``width`` texels along ``u_step`` and ``height`` along ``v_step``
    (GL's convention: texel centres at ``(p + 0.5) / width``).

    Attributes
    ----------
    origin : ndarray, shape (3,)
        Corner of texel ``(0, 0)`` in the volume frame (mm).
    u_step, v_step : ndarray, shape (3,)
        One texel along the slice's ``u_axis`` and ``v_axis`` (mm).
    rgba : ndarray, shape (height, width, 4), float32
        Premultiplied colour and opacity (opacity corrected for the stack's ``path_step``).
    """

    origin: np.ndarray
    u_step: np.ndarray
    v_step: np.ndarray
    rgba: np.ndarray

    def texture_coordinates(self, points: np.ndarray) -> np.ndarray:
        """``(s, t)`` of points ``(n, 3)`` lying in the slice, ``(n, 2)``."""
        height, width = self.rgba.shape[:2]
        relative = np.asarray(points, dtype=np.float64) - self.origin
        s = relative @ self.u_step / (self.u_step @ self.u_step) / width
        t = relative @ self.v_step / (self.v_step @ self.v_step) / height
        return np.stack([s, t], axis=-1)


@dataclass(frozen=True)
class TextureChunk:
    """The textures of consecutive visible slices in one flat array.

    Attributes
    ----------
    indices : ndarray, shape (m,), int64
        The slices (indices into the layout's polygons), back to front.
    starts : ndarray, shape (m,), int64
        First texel of each texture in ``textures``; texture ``m`` holds ``height * width`` texels, row by row
        (rows along ``v``, ``width`` texels along ``u`` each), ``height, width = layout.shapes[indices[m]]``.
    textures : ndarray, shape (texels, 4), float32
        Premultiplied RGBA.
    """

    indices: np.ndarray
    starts: np.ndarray
    textures: np.ndarray


@dataclass(frozen=True)
class SliceLayout:
    """The slices of one frame, the pixels each can cover and the texel grid of each texture.

    Attributes
    ----------
    polygons : SlicePolygons
        The slices, back to front.
    rows, columns : ndarray, shape (n, 2), int64
        Half-open ranges of image rows (row 0 at the top) and columns whose pixel centres a slice can cover;
        empty ranges for slices outside the image or behind a perspective camera.
    origins, u_steps, v_steps : ndarray, shape (n, 3)
        Texture grid of each slice (see :class:`SliceTexture`).
    shapes : ndarray, shape (n, 2), int64
        ``(height, width)`` of each texture in texels; ``(0, 0)`` for slices that cover no pixel.
    pixel_aligned : bool
        Whether texel centres coincide with the pixel rays (view-aligned slices at the default texel size).
    """

    polygons: SlicePolygons
    rows: np.ndarray
    columns: np.ndarray
    origins: np.ndarray
    u_steps: np.ndarray
    v_steps: np.ndarray
    shapes: np.ndarray
    pixel_aligned: bool

    @property
    def visible(self) -> np.ndarray:
        """``(n,)`` bool: slices that cover at least one pixel centre's range."""
        return self.shapes.min(axis=1) > 0


def pixel_bounds(polygons: SlicePolygons, camera: Camera, width: int, height: int):
    """Per slice, the half-open pixel row and column ranges ``(n, 2)`` whose centres the polygon can cover.

    Slices wholly behind a perspective camera get empty ranges; slices reaching behind it get the whole image
    (their projection is unbounded).
    """
    n = len(polygons)
    valid = np.arange(MAX_POLYGON_VERTICES)[None, :] < polygons.counts[:, None]
    points = np.nan_to_num(polygons.vertices.reshape(-1, 3))
    depth = ((points - np.asarray(camera.position)) @ camera.direction).reshape(n, -1)
    if camera.parallel_projection:
        in_front = np.ones(n, dtype=bool)
        behind = np.zeros(n, dtype=bool)
    else:
        in_front = np.all(np.where(valid, depth, 1.0) > 0, axis=1)
        behind = np.all(np.where(valid, depth, -1.0) <= 0, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # vertices in the camera's plane project to infinity
        pixels = camera.project(points, width, height).reshape(n, -1, 2)
    low = np.where(valid[..., None], pixels, np.inf).min(axis=1)
    high = np.where(valid[..., None], pixels, -np.inf).max(axis=1)
    # Pixel centres sit at index + 0.5, so the covered indices lie in [low - 0.5, high - 0.5]; one pixel of margin
    # on either side absorbs rounding.
    size = np.array([width, height])
    with np.errstate(invalid="ignore"):
        first = np.clip(np.floor(low - 0.5) - 1, 0, size).astype(np.int64)
        last = np.clip(np.ceil(high - 0.5) + 2, 0, size).astype(np.int64)
    columns = np.where(in_front[:, None], np.stack([first[:, 0], last[:, 0]], axis=1), [0, width])
    rows = np.where(in_front[:, None], np.stack([first[:, 1], last[:, 1]], axis=1), [0, height])
    columns[behind] = 0
    rows[behind] = 0
    return rows.astype(np.int64), columns.astype(np.int64)


def bounding_textures(polygons: SlicePolygons, u_size: float, v_size: float):
    """Texture grids of ``u_size`` x ``v_size`` mm texels covering each polygon: texel centres from the polygon's
    smallest ``u`` and ``v`` onwards, up to or one texel beyond the largest. Returns origins, u and v steps,
    shapes ``(height, width)``."""
    u = polygons.vertices @ polygons.u_axis
    v = polygons.vertices @ polygons.v_axis
    u_low, u_high = np.nanmin(u, axis=1), np.nanmax(u, axis=1)
    v_low, v_high = np.nanmin(v, axis=1), np.nanmax(v, axis=1)
    widths = np.ceil((u_high - u_low) / u_size - 1e-6).astype(np.int64) + 1
    heights = np.ceil((v_high - v_low) / v_size - 1e-6).astype(np.int64) + 1
    origins = (polygons.offsets[:, None] * polygons.normal + (u_low - 0.5 * u_size)[:, None] * polygons.u_axis
               + (v_low - 0.5 * v_size)[:, None] * polygons.v_axis)
    n = len(polygons)
    u_steps = np.tile(u_size * polygons.u_axis, (n, 1))
    v_steps = np.tile(v_size * polygons.v_axis, (n, 1))
    return origins, u_steps, v_steps, np.stack([heights, widths], axis=1)


def pixel_textures(polygons: SlicePolygons, camera: Camera, width: int, height: int, rows, columns):
    """Texture grids of view-aligned slices whose texel centres are the points where the pixel rays meet the
    slice: one texel per pixel of the slice's pixel range, texel column ``p`` = image column ``columns[s, 0] + p``,
    texel row ``q`` = image row ``rows[s, 1] - 1 - q`` (texture rows go up, image rows down)."""
    frame = camera.ray_frame(width, height)
    position = np.asarray(camera.position)
    depth = polygons.offsets - polygons.normal @ position  # distance of each plane from the camera along f
    if camera.parallel_projection:
        scale = np.ones(len(polygons))
        corner = frame[0] + (polygons.offsets - frame[0] @ polygons.normal)[:, None] * frame[1]
    else:
        scale = depth  # every pixel ray has f . d = 1, so it meets the plane at t = depth
        corner = position + depth[:, None] * frame[1]
    u_steps = scale[:, None] * frame[2]
    v_steps = -scale[:, None] * frame[3]
    # The centre of pixel (col, row) on the plane is corner + col u_step - row v_step.
    origins = (corner + (columns[:, :1] - 0.5) * u_steps - (rows[:, 1:] - 1 + 0.5) * v_steps)
    shapes = np.stack([rows[:, 1] - rows[:, 0], columns[:, 1] - columns[:, 0]], axis=1)
    return origins, u_steps, v_steps, np.maximum(shapes, 0)


def layout_stats(layout: SliceLayout) -> dict[str, float]:
    """Numbers describing a frame's slices: ``slices`` (drawn), ``slice_distance_mm``, ``path_step_mm`` (what the
    opacity is corrected for), ``texels`` (resampled in all textures), ``texel_size_mm`` (mean texel edge along
    ``u`` over the drawn slices), ``axis`` (stack axis, -1 for view-aligned slices)."""
    visible = layout.visible
    shapes = layout.shapes[visible]
    texel = np.linalg.norm(layout.u_steps[visible], axis=1)
    return {
        "slices": float(visible.sum()),
        "slice_distance_mm": float(layout.polygons.slice_distance),
        "path_step_mm": float(layout.polygons.path_step),
        "texels": float((shapes[:, 0] * shapes[:, 1]).sum()),
        "texel_size_mm": float(texel.mean()) if len(texel) else 0.0,
        "axis": float(-1 if layout.polygons.axis is None else layout.polygons.axis),
    }
