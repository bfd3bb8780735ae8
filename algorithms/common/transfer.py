"""Transfer functions as 1D lookup tables, with VTK's opacity semantics.

A :class:`TransferTable` maps a scalar value to colour and opacity by linear interpolation in a table sampled
evenly over ``[value_min, value_max]``; values outside the range take the end entries (VTK's clamping). Opacity
is *per unit distance*: the opacity a slab of thickness ``unit_distance`` (mm) contributes. A renderer taking
samples ``d`` mm apart uses the corrected per-sample opacity ``1 - (1 - a) ** (d / unit_distance)``, which is
what ``vtkVolumeProperty.SetScalarOpacityUnitDistance`` means in VTK's mappers.

References
----------
Source 002 (Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009), section 2.4.1
(the lookup). Source 004 (Tavira Rodríguez de Liébana, *Optimización del renderizado de volumen mediante la técnica
shear-warping*, 2017), section 5.2.6 (the opacity correction). N. Max, *Optical models for direct volume
rendering*, IEEE Transactions on Visualization and Computer Graphics 1(2), 1995, doi:10.1109/2945.468400 (the
exponential absorption the correction follows from).

The application builds these tables from its presets (``app.transfer``), the same presets that build VTK's
``vtkColorTransferFunction`` and ``vtkPiecewiseFunction``, so one preset means one picture in every mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _piecewise(points: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation through control points ``(n, 1 + c)`` at ``samples``; clamped ends."""
    points = np.asarray(points, dtype=np.float64)
    order = np.argsort(points[:, 0], kind="stable")
    points = points[order]
    out = np.empty((len(samples), points.shape[1] - 1))
    for c in range(points.shape[1] - 1):
        out[:, c] = np.interp(samples, points[:, 0], points[:, c + 1])
    return out


@dataclass(frozen=True)
class TransferTable:
    """RGBA lookup table over a value range.

    Parameters
    ----------
    rgba : ndarray, shape (n, 4), float32
        Colour in ``[0, 1]`` (not premultiplied) and opacity per ``unit_distance`` in ``[0, 1]``.
    value_min, value_max : float
        Scalar values of the first and last entry.
    unit_distance : float
        Distance in mm over which an entry's opacity applies.
    """

    rgba: np.ndarray
    value_min: float
    value_max: float
    unit_distance: float = 1.0

    def __post_init__(self) -> None:
        rgba = np.ascontiguousarray(self.rgba, dtype=np.float32)
        if rgba.ndim != 2 or rgba.shape[1] != 4 or len(rgba) < 2:
            raise ValueError(f"rgba must have shape (n >= 2, 4), got {rgba.shape}")
        if not (np.all(rgba >= 0) and np.all(rgba <= 1)):
            raise ValueError("rgba entries must lie in [0, 1]")
        if not self.value_max > self.value_min:
            raise ValueError(f"value_max ({self.value_max}) must exceed value_min ({self.value_min})")
        if self.unit_distance <= 0:
            raise ValueError(f"unit_distance must be positive, got {self.unit_distance}")
        rgba.setflags(write=False)
        object.__setattr__(self, "rgba", rgba)

    @classmethod
    def from_points(
        cls,
        color_points,
        opacity_points,
        value_range: tuple[float, float],
        *,
        size: int = 4096,
        unit_distance: float = 1.0,
    ) -> "TransferTable":
        """Sample piecewise-linear control points into a table over ``value_range``.

        ``color_points`` are rows ``(value, r, g, b)`` and ``opacity_points`` rows ``(value, opacity)``, exactly
        what ``vtkColorTransferFunction.AddRGBPoint`` and ``vtkPiecewiseFunction.AddPoint`` take.
        """
        color_points = np.asarray(color_points, dtype=np.float64).reshape(-1, 4)
        opacity_points = np.asarray(opacity_points, dtype=np.float64).reshape(-1, 2)
        if len(color_points) == 0 or len(opacity_points) == 0:
            raise ValueError("a transfer function needs at least one colour and one opacity point")
        lo, hi = float(value_range[0]), float(value_range[1])
        if not hi > lo:
            raise ValueError(f"empty value range {value_range}")
        samples = np.linspace(lo, hi, size)
        rgba = np.empty((size, 4), dtype=np.float32)
        rgba[:, :3] = np.clip(_piecewise(color_points, samples), 0, 1)
        rgba[:, 3] = np.clip(_piecewise(opacity_points, samples)[:, 0], 0, 1)
        return cls(rgba, lo, hi, unit_distance)

    def same_as(self, other: "TransferTable") -> bool:
        """Same range, unit distance and entries (dataclass equality cannot compare the arrays)."""
        return self is other or (
            self.value_min == other.value_min and self.value_max == other.value_max
            and self.unit_distance == other.unit_distance and self.rgba.shape == other.rgba.shape
            and bool(np.array_equal(self.rgba, other.rgba))
        )

    @property
    def size(self) -> int:
        return len(self.rgba)

    @property
    def scale(self) -> float:
        """Table entries per unit of scalar value (``index = (value - value_min) * scale``)."""
        return (self.size - 1) / (self.value_max - self.value_min)

    def corrected(self, sample_distance: float) -> np.ndarray:
        """The table with opacity corrected for samples ``sample_distance`` mm apart, ``(n, 4)`` float32."""
        if sample_distance <= 0:
            raise ValueError(f"sample_distance must be positive, got {sample_distance}")
        table = np.array(self.rgba, dtype=np.float32)
        table[:, 3] = 1.0 - np.power(1.0 - self.rgba[:, 3].astype(np.float64), sample_distance / self.unit_distance)
        return table

    def lookup(self, values: np.ndarray, table: np.ndarray | None = None) -> np.ndarray:
        """RGBA of ``values`` (any shape) by linear interpolation in ``table`` (default: uncorrected)."""
        table = self.rgba if table is None else table
        position = np.clip((np.asarray(values, dtype=np.float64) - self.value_min) * self.scale, 0, self.size - 1)
        index = np.minimum(position.astype(np.int64), self.size - 2)
        frac = (position - index)[..., None]
        return (table[index] * (1 - frac) + table[index + 1] * frac).astype(np.float32)

    def opaque_value_range(self, threshold: float = 0.0) -> tuple[float, float] | None:
        """Smallest value interval outside which opacity is ``<= threshold`` (None if nothing is visible)."""
        visible = np.nonzero(self.rgba[:, 3] > threshold)[0]
        if len(visible) == 0:
            return None
        entry_width = 1.0 / self.scale
        lo = self.value_min + max(visible[0] - 1, 0) * entry_width
        hi = self.value_min + min(visible[-1] + 1, self.size - 1) * entry_width
        return lo, hi


def checked_table(table, *, error: type[Exception] = TypeError) -> TransferTable:
    """``table`` itself if it is a :class:`TransferTable`; ``error`` (TypeError unless given) naming it otherwise."""
    if not isinstance(table, TransferTable):
        raise error(f"table must be an algorithms.common.transfer.TransferTable, got {type(table).__name__}")
    return table
