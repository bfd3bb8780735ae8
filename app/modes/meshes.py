"""Modes for meshes of the scene: a surface mesh (read from a file or made by an operation) shown as it is."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..pipeline.content import IGNORE, REDRAW, ViewInputs
from ..pipeline.lit_surfaces import LitContent, polydata_stats
from ..pipeline.props import surface_actor
from . import register_mode
from .base import Mode, Option


@dataclass(frozen=True)
class MeshMode(Mode):
    def create_content(self, options: Mapping[str, Any]) -> "MeshContent":
        return MeshContent(self, options)


class MeshContent(LitContent):
    """A triangle mesh of the scene, shown as it is (patient coordinates)."""

    def install(self, renderer, inputs: ViewInputs, prepared: Any) -> None:
        polydata = inputs.item.polydata
        self.stats = polydata_stats(polydata)
        actor = surface_actor(polydata, None, color=(0.85, 0.85, 0.85), flat=self.options.get("flat", False))
        bounds = np.asarray(polydata.GetBounds(), dtype=np.float64)
        diagonal = float(np.linalg.norm(bounds[1::2] - bounds[::2])) if polydata.GetNumberOfPoints() else 0.0
        self._replace_props(renderer, [actor], detail_mm=diagonal / 200.0)

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        return REDRAW if change == "background" else IGNORE

    def status(self) -> str:
        s = self.stats
        return f"{s['points']:,} points, {s['triangles']:,} triangles" if s else ""

    def surface(self):
        return None


register_mode(MeshMode(
    "mesh", "Surface mesh", "A triangle mesh of the scene as it is (patient coordinates, mm)", group="Meshes",
    origin="ours", input="mesh", output="surface",
    options=(Option("flat", "bool", False, "mesh: flat shading (one normal per triangle) instead of smooth"),),
))
