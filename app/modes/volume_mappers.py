"""VTK's ray-cast volume mappers as modes: ``vtkGPUVolumeRayCastMapper`` (OpenGL; Mesa llvmpipe without a GPU) and
``vtkFixedPointVolumeRayCastMapper`` (multi-threaded CPU). They are the references our renderers are measured
against."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from ..pipeline.volumes import VolumeMapperContent
from . import register_mode
from .base import Capabilities, Mode


@dataclass(frozen=True)
class VolumeMapperMode(Mode):
    """A VTK volume mapper; ``mapper`` is ``"gpu"`` or ``"cpu"``."""

    mapper: str = "gpu"

    def create_content(self, options: Mapping[str, Any]) -> VolumeMapperContent:
        return VolumeMapperContent(self, options)


VOLUME = dict(group="Volume rendering", origin="VTK", input="volume", output="volume",
              capabilities=Capabilities(uses_transfer_function=True, accepts_selection=True))

register_mode(VolumeMapperMode(
    "vtk-gpu", "GPU ray casting", "VTK's vtkGPUVolumeRayCastMapper (OpenGL; Mesa llvmpipe without a GPU)",
    **VOLUME, mapper="gpu",
))
register_mode(VolumeMapperMode(
    "vtk-cpu", "CPU ray casting", "VTK's vtkFixedPointVolumeRayCastMapper (multi-threaded CPU)", **VOLUME,
    mapper="cpu",
))
