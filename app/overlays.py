"""Fields drawn over a volume's slices: masks, distance fields and label maps resampled onto the volume's grid and
coloured for display. Qt-free, so the slice views and the tests share it.

- masks: the inside (value >= 0.5) in a translucent colour;
- distance fields (mm, negative inside): a diverging map, blue inside to red outside, fading out beyond ``band_mm``,
  with the zero level (the surface) drawn solid;
- label maps: one colour per label from the map's colour table (:class:`app.labels.LabelTable`: ITK-SNAP, 3D Slicer,
  AAL... files) or a generated distinct palette, at an adjustable opacity (0 is transparent).

Values outside the field (NaN, as :func:`app.slices.sample_plane` returns them) are transparent.
"""

from __future__ import annotations

import numpy as np

MASK_RGBA = (1.0, 0.25, 0.2, 0.45)
DISTANCE_ALPHA = 0.55


def overlay_volume(base, field_item, *, progress=None):
    """The field of ``field_item`` sampled at the voxel centres of ``base`` (a Volume): nearest for masks and labels,
    trilinear for distances. A field already on ``base``'s grid is returned as it is."""
    volume = field_item.volume
    if volume.grid.same_as(base.grid):
        return volume
    order = 1 if field_item.role == "distance" else 0
    fill = float(volume.value_range[1]) if field_item.role == "distance" else 0.0
    return volume.resampled(base.grid, order=order, fill=fill, progress=progress)


def overlay_rgba(values: np.ndarray, role: str, *, band_mm: float | None = None, table=None,
                 opacity: float | None = None) -> np.ndarray:
    """Colours ``(..., 4)`` float32 in [0, 1] (straight alpha) for field values of a role. For labels, ``table`` (a
    :class:`app.labels.LabelTable`) gives the colours and ``opacity`` their alpha (default 0.5)."""
    values = np.asarray(values)
    rgba = np.zeros(values.shape + (4,), dtype=np.float32)
    if role == "mask":
        inside = values >= 0.5
        rgba[inside] = MASK_RGBA
    elif role == "distance":
        finite = np.isfinite(values)
        band = band_mm if band_mm and band_mm > 0 else max(float(np.nanmax(np.abs(values[finite]))) if finite.any()
                                                            else 1.0, 1e-6)
        t = np.clip(values / band, -1.0, 1.0)
        rgba[..., 0] = np.where(t > 0, 1.0, 1.0 + t)  # white at 0, red outside, blue inside
        rgba[..., 1] = 1.0 - np.abs(t)
        rgba[..., 2] = np.where(t < 0, 1.0, 1.0 - t)
        rgba[..., 3] = DISTANCE_ALPHA * (1.0 - np.abs(t) ** 2)
        rgba[~finite] = 0.0
    elif role == "labels":
        labels = np.where(np.isfinite(values), values, 0).astype(np.int64) if values.dtype.kind == "f" \
            else values.astype(np.int64)
        count = int(labels.max()) + 1 if labels.size else 1
        alpha = 0.5 if opacity is None else float(opacity)
        if table is not None:
            palette = table.rgba(count, alpha)
        else:
            palette = label_palette(count)
            palette[1:, 3] = alpha
        rgba[...] = palette[np.clip(labels, 0, len(palette) - 1)]
    else:
        raise ValueError(f"no overlay colours for a field of role {role!r}")
    return rgba


def label_palette(count: int) -> np.ndarray:
    """``count`` distinct colours (golden-angle hues), label 0 transparent; ``(count, 4)`` float32."""
    hues = (np.arange(count) * 0.618033988749895) % 1.0
    palette = np.zeros((max(count, 1), 4), dtype=np.float32)
    h = hues * 6.0
    x = 1.0 - np.abs(h % 2.0 - 1.0)
    sector = h.astype(int) % 6
    rgb = np.select([sector[:, None] == s for s in range(6)],
                    [np.stack(c, axis=1) for c in ((np.ones_like(x), x, 0 * x), (x, np.ones_like(x), 0 * x),
                                                   (0 * x, np.ones_like(x), x), (0 * x, x, np.ones_like(x)),
                                                   (x, 0 * x, np.ones_like(x)), (np.ones_like(x), 0 * x, x))])
    palette[:, :3] = 0.25 + 0.75 * rgb
    palette[:, 3] = 0.5
    palette[0] = 0.0
    return palette
