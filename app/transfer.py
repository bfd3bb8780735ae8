"""Transfer-function presets, defined once and used by every render mode.

A preset gives colour and opacity control points, either in absolute values (Hounsfield units for the CT presets)
or relative to a volume's robust value range, its 0.5th to 99.5th percentile (MR and generic presets, whose
intensities have no fixed scale).
Resolving a preset against a volume gives a :class:`TransferFunction`, which builds

- VTK's ``vtkVolumeProperty`` (``vtkColorTransferFunction`` + ``vtkPiecewiseFunction``, linear interpolation,
  ``ScalarOpacityUnitDistance``) for the ``vtk-gpu`` and ``vtk-cpu`` modes, and
- our :class:`algorithms.common.transfer.TransferTable` for ``raymarch``, ``slicing`` and ``shear-warp``,

with the same meaning: piecewise-linear colour and opacity, clamped outside the control points, opacity per
``unit_distance`` millimetres, corrected for the sample distance as ``1 - (1 - a) ** (step / unit_distance)``.
The names follow 3D Slicer's volume-rendering presets (CT-Bone, CT-Skin, ...); the control points are our own.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from algorithms.common.transfer import TransferTable


@dataclass(frozen=True)
class Shading:
    """Blinn-Phong material of a volume (VTK's vtkVolumeProperty terms)."""

    enabled: bool = False
    ambient: float = 0.2
    diffuse: float = 0.7
    specular: float = 0.3
    specular_power: float = 10.0

    def __post_init__(self) -> None:
        for name in ("ambient", "diffuse", "specular"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {value}")
        if self.specular_power <= 0:
            raise ValueError(f"specular_power must be positive, got {self.specular_power}")


@dataclass(frozen=True)
class TransferFunction:
    """Absolute colour and opacity control points plus shading; the single source of every mode's mapping.

    ``color_points`` rows are ``(value, r, g, b)`` and ``opacity_points`` rows ``(value, opacity)``, values in the
    volume's units, colours and opacities in [0, 1]; opacity applies per ``unit_distance`` mm.
    """

    name: str
    color_points: tuple[tuple[float, float, float, float], ...]
    opacity_points: tuple[tuple[float, float], ...]
    unit_distance: float = 1.0
    shading: Shading = field(default_factory=Shading)

    def __post_init__(self) -> None:
        colors = np.asarray(self.color_points, dtype=np.float64).reshape(-1, 4)
        opacities = np.asarray(self.opacity_points, dtype=np.float64).reshape(-1, 2)
        if len(colors) == 0 or len(opacities) == 0:
            raise ValueError("a transfer function needs at least one colour point and one opacity point")
        if np.any(colors[:, 1:] < 0) or np.any(colors[:, 1:] > 1):
            raise ValueError("colour components must lie in [0, 1]")
        if np.any(opacities[:, 1] < 0) or np.any(opacities[:, 1] > 1):
            raise ValueError("opacities must lie in [0, 1]")
        if self.unit_distance <= 0:
            raise ValueError(f"unit_distance must be positive (mm), got {self.unit_distance}")
        object.__setattr__(self, "color_points", tuple(tuple(map(float, row)) for row in colors[np.argsort(colors[:, 0], kind="stable")]))
        object.__setattr__(self, "opacity_points", tuple(tuple(map(float, row)) for row in opacities[np.argsort(opacities[:, 0], kind="stable")]))

    # -- edits (the curve editor works through these) ---------------------------------------------------------
    def with_opacity_points(self, points: Sequence[Sequence[float]]) -> "TransferFunction":
        return replace(self, opacity_points=tuple(tuple(p) for p in points))

    def with_color_points(self, points: Sequence[Sequence[float]]) -> "TransferFunction":
        return replace(self, color_points=tuple(tuple(p) for p in points))

    def with_shading(self, shading: Shading) -> "TransferFunction":
        return replace(self, shading=shading)

    @property
    def value_range(self) -> tuple[float, float]:
        """Smallest and largest control-point value."""
        values = [p[0] for p in self.color_points] + [p[0] for p in self.opacity_points]
        return min(values), max(values)

    # -- builders --------------------------------------------------------------------------------------------
    def to_table(self, value_range: tuple[float, float], *, size: int = 4096) -> TransferTable:
        """Our lookup table over ``value_range`` widened to cover every control point (clamped ends as in VTK)."""
        lo = min(value_range[0], self.value_range[0])
        hi = max(value_range[1], self.value_range[1])
        if hi <= lo:
            hi = lo + 1.0
        return TransferTable.from_points(
            self.color_points, self.opacity_points, (lo, hi), size=size, unit_distance=self.unit_distance
        )

    def to_vtk_functions(self):
        """``(vtkColorTransferFunction, vtkPiecewiseFunction)`` with the same points (clamping on)."""
        from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction
        from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

        color = vtkColorTransferFunction()
        color.SetColorSpaceToRGB()
        color.ClampingOn()
        for value, r, g, b in self.color_points:
            color.AddRGBPoint(value, r, g, b)
        opacity = vtkPiecewiseFunction()
        opacity.ClampingOn()
        for value, a in self.opacity_points:
            opacity.AddPoint(value, a)
        return color, opacity

    def to_vtk_property(self, *, shading: bool | None = None):
        """A ``vtkVolumeProperty``: linear interpolation, opacity unit distance, shading as configured."""
        from vtkmodules.vtkRenderingCore import vtkVolumeProperty

        color, opacity = self.to_vtk_functions()
        prop = vtkVolumeProperty()
        prop.SetColor(color)
        prop.SetScalarOpacity(opacity)
        prop.SetInterpolationTypeToLinear()
        prop.SetScalarOpacityUnitDistance(self.unit_distance)
        shade = self.shading.enabled if shading is None else shading
        prop.SetShade(int(shade))
        prop.SetAmbient(self.shading.ambient)
        prop.SetDiffuse(self.shading.diffuse)
        prop.SetSpecular(self.shading.specular)
        prop.SetSpecularPower(self.shading.specular_power)
        return prop


@dataclass(frozen=True)
class Preset:
    """A named transfer function; ``relative`` points are fractions of the volume's robust value range."""

    name: str
    description: str
    color_points: tuple[tuple[float, float, float, float], ...]
    opacity_points: tuple[tuple[float, float], ...]
    relative: bool = False
    units: str = ""
    unit_distance: float = 1.0
    shading: Shading = field(default_factory=lambda: Shading(enabled=True))

    def resolve(self, value_range: tuple[float, float] | None = None) -> TransferFunction:
        """The absolute transfer function; relative presets need ``value_range`` (see ``Volume.percentile_range``)."""
        colors = np.asarray(self.color_points, dtype=np.float64)
        opacities = np.asarray(self.opacity_points, dtype=np.float64)
        if self.relative:
            if value_range is None:
                raise ValueError(f"preset {self.name!r} is relative to the data range; give value_range")
            lo, hi = float(value_range[0]), float(value_range[1])
            if hi <= lo:
                hi = lo + 1.0
            colors = colors.copy()
            opacities = opacities.copy()
            colors[:, 0] = lo + colors[:, 0] * (hi - lo)
            opacities[:, 0] = lo + opacities[:, 0] * (hi - lo)
        return TransferFunction(self.name, tuple(map(tuple, colors)), tuple(map(tuple, opacities)),
                                self.unit_distance, self.shading)


_BONE = (0.91, 0.82, 0.55)
PRESETS: dict[str, Preset] = {
    preset.name: preset
    for preset in (
        Preset(
            "ct-bone",
            "CT bone: soft tissue transparent, bone from about 200 HU opaque ivory",
            ((-1024, 0.0, 0.0, 0.0), (200, 0.73, 0.25, 0.30), (700, *_BONE), (3071, 1.0, 1.0, 1.0)),
            ((-1024, 0.0), (200, 0.0), (700, 0.6), (3071, 0.8)),
            units="HU",
        ),
        Preset(
            "ct-skin",
            "CT skin: the air/skin boundary from about -500 HU, bone brighter underneath",
            ((-1024, 0.0, 0.0, 0.0), (-500, 0.55, 0.25, 0.15), (0, 0.93, 0.74, 0.62), (500, 1.0, 0.94, 0.85),
             (3071, 1.0, 1.0, 1.0)),
            ((-1024, 0.0), (-500, 0.0), (-200, 0.35), (200, 0.35), (600, 0.7), (3071, 0.8)),
            units="HU",
        ),
        Preset(
            "ct-soft-tissue",
            "CT soft tissue: faint fat and muscle (-100 to 100 HU), bone as context",
            ((-1024, 0.0, 0.0, 0.0), (-100, 0.55, 0.30, 0.20), (40, 0.85, 0.45, 0.40), (150, 0.95, 0.80, 0.70),
             (400, *_BONE), (3071, 1.0, 1.0, 1.0)),
            ((-1024, 0.0), (-150, 0.0), (-50, 0.01), (40, 0.03), (120, 0.03), (300, 0.4), (3071, 0.7)),
            units="HU",
        ),
        Preset(
            "mr-default",
            "MR: intensities above about a quarter of the range, dark red to white",
            ((0.0, 0.0, 0.0, 0.0), (0.25, 0.45, 0.20, 0.15), (0.6, 0.90, 0.75, 0.65), (1.0, 1.0, 1.0, 1.0)),
            ((0.0, 0.0), (0.25, 0.0), (0.6, 0.15), (1.0, 0.35)),
            relative=True,
        ),
        Preset(
            "grayscale",
            "Grey levels: colour and opacity both rise linearly over the data range",
            ((0.0, 0.0, 0.0, 0.0), (1.0, 1.0, 1.0, 1.0)),
            ((0.0, 0.0), (1.0, 0.1)),
            relative=True,
            shading=Shading(enabled=False),
        ),
    )
}


def preset_names() -> list[str]:
    return list(PRESETS)


def get_preset(name: str) -> Preset:
    """The preset called ``name`` (ValueError naming the choices otherwise)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}") from None


def default_preset_name(volume) -> str:
    """``ct-bone`` for CT in HU, ``mr-default`` otherwise."""
    return "ct-bone" if volume.units == "HU" else "mr-default"


def transfer_function_for(volume, preset_name: str | None = None, *, shading: bool | None = None) -> TransferFunction:
    """Resolve a preset (default: :func:`default_preset_name`) for ``volume``; ``shading`` overrides the preset's."""
    preset = get_preset(preset_name or default_preset_name(volume))
    function = preset.resolve(volume.percentile_range() if preset.relative else None)
    if shading is not None:
        function = function.with_shading(replace(function.shading, enabled=bool(shading)))
    return function
