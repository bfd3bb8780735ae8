"""Modes for meshes of the scene: a surface mesh (read from a file or made by an operation) shown as it is."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from ..pipeline.surfaces import MeshContent
from . import register_mode
from .base import Mode, Option


@dataclass(frozen=True)
class MeshMode(Mode):
    def create_content(self, options: Mapping[str, Any]) -> MeshContent:
        return MeshContent(self, options)


register_mode(MeshMode(
    "mesh", "Surface mesh", "A triangle mesh of the scene as it is (patient coordinates, mm)", group="Meshes",
    origin="ours", input="mesh", output="surface",
    options=(Option("flat", "bool", False, "mesh: flat shading (one normal per triangle) instead of smooth"),),
))
