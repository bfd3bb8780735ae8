"""Measurements on a volume, without Qt: distances (mm), angles (degrees), and region statistics (mean, SD,
minimum, maximum in the volume's units; area in mm^2 or volume in mm^3) of an ellipse on a slice or of the inside
of a mask (a cut-away tool's field).

Points are LPS millimetres. An ellipse lies in a slice plane (:mod:`app.slices`): centre, the plane's screen axes
``u`` and ``v`` and the semi-axes along them (mm); its statistics cover the pixels of that slice whose centres lie
inside it, sampled as the slice view shows them (:func:`app.slices.sample_plane`: on an axis-aligned slice these
are exactly the stored voxels; on an oblique one, trilinear samples), and its area is their number times the pixel
area. A mask's statistics cover the volume's voxels where the mask (resampled onto the volume's grid, nearest
neighbour) is at least 0.5, and its volume is their number times the voxel volume.

:class:`MeasurementList` holds them with change signals (the window's Measurements panel), and writes CSV and the
JSON form sessions store.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .events import Signal
from .slices import PlaneFrame, plane_grid, sample_plane, voxel_aligned

KINDS = ("distance", "angle", "ellipse", "mask")
CSV_COLUMNS = ("name", "kind", "value", "unit", "mean", "sd", "min", "max", "value_units", "pixels", "plane",
               "points_lps_mm")


def _point(value) -> np.ndarray:
    point = np.asarray(value, dtype=np.float64).reshape(-1)
    if point.shape != (3,) or not np.all(np.isfinite(point)):
        raise ValueError(f"a point is three finite LPS millimetre values, got {value!r}")
    return point


def distance_mm(p0, p1) -> float:
    return float(np.linalg.norm(_point(p1) - _point(p0)))


def angle_degrees(p0, vertex, p1) -> float:
    """The angle at ``vertex`` between the rays to ``p0`` and ``p1`` (0 to 180 degrees)."""
    a, b = _point(p0) - _point(vertex), _point(p1) - _point(vertex)
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        raise ValueError("an angle needs two points apart from its vertex")
    cosine = np.clip(a @ b / (na * nb), -1.0, 1.0)
    return float(np.degrees(np.arccos(cosine)))


def value_statistics(values: np.ndarray) -> dict[str, float]:
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        raise ValueError("the region holds no voxel of the volume")
    return {"mean": float(values.mean()), "sd": float(values.std(ddof=0)), "min": float(values.min()),
            "max": float(values.max()), "pixels": int(values.size)}


def ellipse_pixels(grid, centre, radii: Sequence[float]) -> np.ndarray:
    """Boolean ``grid.shape`` mask of the plane grid's pixels whose centres lie inside the ellipse."""
    a, b = (float(r) for r in radii)
    if not (a > 0 and b > 0):
        raise ValueError(f"an ellipse needs two positive semi-axes (mm), got {a:g} and {b:g}")
    sc, tc = grid.to_plane(centre)
    s = grid.s0 + np.arange(grid.columns) * grid.ds
    t = grid.t0 - np.arange(grid.rows) * grid.dt
    return ((s[None, :] - sc) / a) ** 2 + ((t[:, None] - tc) / b) ** 2 <= 1.0


@dataclass
class Measurement:
    """One measurement. ``points`` (LPS mm): distance p0, p1; angle p0, vertex, p1; ellipse its centre.
    ``plane``: the slice plane name (ellipses; and where a point measurement was made, ``"3d"`` for 3D views).
    ``frame``: the ellipse plane's ``(u, v)`` (LPS unit vectors); ``radii``: its semi-axes (mm);
    ``mask``: the mask item's name. ``results`` holds the numbers (see :meth:`compute`)."""

    kind: str
    name: str = ""
    points: list[list[float]] = field(default_factory=list)
    plane: str = ""
    frame: list[list[float]] | None = None
    radii: list[float] | None = None
    mask: str = ""
    results: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"measurement kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        self.points = [[float(c) for c in _point(p)] for p in self.points]
        needed = {"distance": 2, "angle": 3, "ellipse": 1, "mask": 0}[self.kind]
        if len(self.points) != needed:
            raise ValueError(f"a {self.kind} measurement needs {needed} point(s), got {len(self.points)}")
        if self.kind == "ellipse" and (self.frame is None or self.radii is None):
            raise ValueError("an ellipse needs its plane's axes (frame) and its two semi-axes (radii)")
        if self.kind == "mask" and not self.mask:
            raise ValueError("a mask measurement needs the name of the mask")

    # -- numbers -----------------------------------------------------------------------------------------------
    def compute(self, volume=None, *, mask_volume=None) -> dict[str, Any]:
        """Measure (regions need the ``volume``; a mask measurement its ``mask_volume``); stores and returns the
        results: ``value`` and ``unit``, plus ``mean``, ``sd``, ``min``, ``max``, ``pixels``, ``value_units``."""
        if self.kind == "distance":
            results = {"value": distance_mm(*self.points), "unit": "mm"}
        elif self.kind == "angle":
            results = {"value": angle_degrees(*self.points), "unit": "degrees"}
        elif self.kind == "ellipse":
            results = self._ellipse(volume)
        else:
            results = self._mask(volume, mask_volume)
        self.results = results
        return results

    def _ellipse(self, volume) -> dict[str, Any]:
        if volume is None:
            raise ValueError("region statistics need the volume")
        u, v = (np.asarray(a, dtype=np.float64) for a in self.frame)
        frame = PlaneFrame(self.plane or "axial", u, v, np.cross(u, v))
        grid = plane_grid(volume, frame, self.points[0])
        inside = ellipse_pixels(grid, self.points[0], self.radii)
        order = 0 if voxel_aligned(volume, frame) else 1  # stored voxels where the slice runs through them
        values = sample_plane(volume, grid, order=order)[inside]
        stats = value_statistics(values)
        return {"value": stats["pixels"] * grid.ds * grid.dt, "unit": "mm^2", **stats,
                "value_units": volume.units_label, "semi_axes_mm": [float(r) for r in self.radii]}

    def _mask(self, volume, mask_volume) -> dict[str, Any]:
        if volume is None or mask_volume is None:
            raise ValueError("mask statistics need the volume and the mask")
        if not mask_volume.grid.same_as(volume.grid):
            mask_volume = mask_volume.resampled(volume.grid, order=0, fill=0.0)
        inside = mask_volume.array >= 0.5
        stats = value_statistics(volume.array[inside])
        return {"value": stats["pixels"] * float(np.prod(volume.spacing)), "unit": "mm^3", **stats,
                "value_units": volume.units_label}

    # -- text and rows -----------------------------------------------------------------------------------------
    def summary(self) -> str:
        r = self.results
        if not r:
            return self.kind
        text = f"{r['value']:.2f} {r['unit']}"
        if "mean" in r:
            text += (f"; mean {r['mean']:.1f}, SD {r['sd']:.1f}, min {r['min']:g}, max {r['max']:g} "
                     f"{r['value_units']}")
        return text

    def row(self) -> dict[str, Any]:
        r = self.results
        return {
            "name": self.name, "kind": self.kind, "value": r.get("value"), "unit": r.get("unit"),
            "mean": r.get("mean"), "sd": r.get("sd"), "min": r.get("min"), "max": r.get("max"),
            "value_units": r.get("value_units", ""), "pixels": r.get("pixels"), "plane": self.plane or self.mask,
            "points_lps_mm": ";".join(" ".join(f"{c:.3f}" for c in p) for p in self.points),
        }

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "name": self.name, "points": self.points, "plane": self.plane,
                "frame": self.frame, "radii": self.radii, "mask": self.mask, "results": self.results}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Measurement":
        try:
            return cls(kind=data["kind"], name=data.get("name", ""), points=data.get("points", []),
                       plane=data.get("plane", ""), frame=data.get("frame"), radii=data.get("radii"),
                       mask=data.get("mask", ""), results=dict(data.get("results") or {}))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"a stored measurement is incomplete ({exc})") from None


class MeasurementList:
    """The workbench's measurements in order; ``added(m)``, ``removed(m)`` and ``reset()`` announce changes."""

    def __init__(self) -> None:
        self.added = Signal()
        self.removed = Signal()
        self.reset = Signal()
        self._items: list[Measurement] = []
        self._counter = 0

    def __iter__(self):
        return iter(list(self._items))

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, index: int) -> Measurement:
        return self._items[index]

    def add(self, measurement: Measurement, index: int | None = None) -> Measurement:
        if not measurement.name:
            self._counter += 1
            measurement.name = f"{measurement.kind.capitalize()} {self._counter}"
        if index is None:
            self._items.append(measurement)
        else:
            self._items.insert(index, measurement)
        self.added.emit(measurement)
        return measurement

    def remove(self, measurement: Measurement) -> int:
        index = self._items.index(measurement)
        del self._items[index]
        self.removed.emit(measurement)
        return index

    def replace_all(self, measurements: Sequence[Measurement]) -> None:
        self._items = list(measurements)
        self._counter = len(self._items)
        self.reset.emit()

    def to_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
        writer.writeheader()
        for measurement in self._items:
            writer.writerow({k: ("" if v is None else v) for k, v in measurement.row().items()})
        return buffer.getvalue()

    def write_csv(self, path, *, overwrite: bool = False):
        from .io.atomic import atomic_output

        path = Path(path).expanduser()
        with atomic_output(path, overwrite=overwrite) as temporary:
            temporary.write_text(self.to_csv())
        return path

    def to_list(self) -> list[dict[str, Any]]:
        return [m.to_dict() for m in self._items]
