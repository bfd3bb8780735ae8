"""VTK's ray-cast volume mappers as modes: ``vtkGPUVolumeRayCastMapper`` (OpenGL; Mesa llvmpipe without a GPU) and
``vtkFixedPointVolumeRayCastMapper`` (multi-threaded CPU), on the item's shared image with the view's transfer
function and sample distance. They are the references our renderers are measured against.

Both render on the thread that owns the renderer (VTK requires it for OpenGL), so there is nothing to prepare.
While the camera moves the window lets VTK coarsen its sampling (the host's desired update rate); at rest it samples
at the fixed distance our renderers use too.

Cut-away tools (source 002, 2.5) reach VTK's mappers through what they support: the GPU mapper takes a binary mask
on the volume's own grid (``SetMaskInput``; the tools evaluated at every voxel, rebuilt for each move of a tool -
the 14-180 ms per move our renderers avoid; no smooth ``distance`` cut, no tool normals at the cut); the CPU mapper
takes no mask at all, so it is given a copy of the volume with the removed voxels set to the background value (a data
rewrite per move, exactly what the source's per-sample test avoids).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from algorithms.references.vtk_cutaway import mask_image

from ..pipeline.content import IGNORE, REDRAW, ViewContent, ViewInputs
from ..pipeline.props import volume_prop
from . import register_mode
from .base import Capabilities, Mode


@dataclass(frozen=True)
class VolumeMapperMode(Mode):
    """A VTK volume mapper; ``mapper`` is ``"gpu"`` or ``"cpu"``."""

    mapper: str = "gpu"

    def create_content(self, options: Mapping[str, Any]) -> "VolumeMapperContent":
        return VolumeMapperContent(self, options)


class VolumeMapperContent(ViewContent):
    """The item drawn by one of VTK's ray-cast volume mappers (``mode.mapper`` is ``"gpu"`` or ``"cpu"``)."""

    volume = None

    def install(self, renderer, inputs: ViewInputs, prepared: Any) -> None:
        step = inputs.effective_sample_distance()
        self.volume = volume_prop(inputs.volume, inputs.transfer_function, mapper=self.mode.mapper,
                                  sample_distance=step, image=inputs.item.vtk_image())
        if inputs.interactive:
            # In a window VTK may coarsen sampling while the camera moves (the host's desired update rate).
            self.volume.GetMapper().SetAutoAdjustSampleDistances(1)
        self.stats = {"sample_distance_mm": step}
        self._apply_tools(inputs)
        self._replace_props(renderer, [self.volume])

    def _apply_tools(self, inputs: ViewInputs) -> None:
        """Give the mapper the tools as a mask on its grid (GPU) or a masked copy of the volume (CPU)."""
        from algorithms.common.cutaway import removal_field

        mapper = self.volume.GetMapper()
        tools = inputs.tool_set()
        start = time.perf_counter()
        volume = inputs.volume
        if tools is None:
            if self.mode.mapper == "gpu":
                mapper.SetMaskInput(None)
            else:
                mapper.SetInputData(inputs.item.vtk_image())
            self.stats.pop("cut_seconds", None)
            self.stats.pop("cut", None)
            return
        kept = removal_field(tools, volume.array.shape, volume.spacing) >= 0
        if self.mode.mapper == "gpu":
            mapper.SetMaskInput(mask_image(kept, volume.spacing))
            mapper.SetMaskTypeToBinary()
            self.stats["cut"] = "binary mask on the mapper's grid"
        else:
            background = volume.value_range[0]
            array = np.where(kept, volume.array, np.asarray(background, dtype=volume.array.dtype))
            mapper.SetInputData(volume.with_array(array).to_vtk(local=True))
            self.stats["cut"] = "masked copy of the volume (the CPU mapper takes no mask)"
        self.stats["cut_seconds"] = time.perf_counter() - start

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if self.volume is None:
            return IGNORE
        if change == "transfer_function":
            self.volume.SetProperty(inputs.transfer_function.to_vtk_property())
            return REDRAW
        if change == "sample_distance":
            step = inputs.effective_sample_distance()
            mapper = self.volume.GetMapper()
            mapper.SetSampleDistance(step)
            if hasattr(mapper, "SetInteractiveSampleDistance"):
                mapper.SetInteractiveSampleDistance(step)
            self.stats["sample_distance_mm"] = step
            return REDRAW
        if change == "cutaways":
            self._apply_tools(inputs)
            return REDRAW
        return REDRAW if change == "background" else IGNORE

    def status(self) -> str:
        step = self.stats.get("sample_distance_mm")
        return f"sample step {step:.2f} mm" if step else ""


VOLUME = dict(group="Volume rendering", origin="VTK", input="volume", output="volume",
              capabilities=Capabilities(uses_transfer_function=True, accepts_cutaways=True))

register_mode(VolumeMapperMode(
    "vtk-gpu", "GPU ray casting", "VTK's vtkGPUVolumeRayCastMapper (OpenGL; Mesa llvmpipe without a GPU)",
    **VOLUME, mapper="gpu",
))
register_mode(VolumeMapperMode(
    "vtk-cpu", "CPU ray casting", "VTK's vtkFixedPointVolumeRayCastMapper (multi-threaded CPU)", **VOLUME,
    mapper="cpu",
))
