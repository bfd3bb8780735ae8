"""The image our software renderers return, and compositing it over a background.

Every renderer (ray marching, texture slicing, shear-warp) has the same shape: constructed once per volume and
transfer function (that is the set-up: classification, encodings, gradients), then
``render(camera, width, height, *, progress=None) -> RenderResult`` per frame, with the camera in the volume frame
(see :mod:`algorithms.common.camera`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class RenderResult:
    """One rendered frame.

    Attributes
    ----------
    rgba : ndarray, shape (height, width, 4), float32
        Premultiplied colour and accumulated opacity in [0, 1], row 0 at the top (like PNG files).
    stats : dict
        Per-frame numbers for the status line and benchmarks, e.g. ``samples_per_ray``, ``early_terminated``
        (fraction of rays), ``seconds``.
    """

    rgba: np.ndarray
    stats: dict[str, float] = field(default_factory=dict)

    def over(self, background=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The frame composited over a background colour, ``(height, width, 3)`` float32 in [0, 1]."""
        return composite_over(self.rgba, background)

    def to_uint8(self, background=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The composited frame as ``(height, width, 3)`` uint8, rounded to nearest."""
        return np.clip(np.rint(self.over(background) * 255.0), 0, 255).astype(np.uint8)


def composite_over(rgba: np.ndarray, background=(0.0, 0.0, 0.0)) -> np.ndarray:
    """``C = C_premultiplied + (1 - alpha) * background`` for an ``(h, w, 4)`` premultiplied image."""
    rgba = np.asarray(rgba, dtype=np.float32)
    if rgba.ndim != 3 or rgba.shape[2] != 4:
        raise ValueError(f"expected an (h, w, 4) image, got shape {rgba.shape}")
    background = np.asarray(background, dtype=np.float32).reshape(1, 1, 3)
    return np.clip(rgba[..., :3] + (1.0 - rgba[..., 3:4]) * background, 0.0, 1.0)
