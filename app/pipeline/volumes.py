"""VTK's volume mappers as view content: ``vtkGPUVolumeRayCastMapper`` and ``vtkFixedPointVolumeRayCastMapper``
on the item's shared image, with the view's transfer function and sample distance.

Both render on the thread that owns the renderer (VTK requires it for OpenGL), so there is nothing to prepare.
While the camera moves the window lets VTK coarsen its sampling (the host's desired update rate); at rest it samples
at the fixed distance our renderers use too.
"""

from __future__ import annotations

from typing import Any

from .content import IGNORE, REDRAW, ViewContent, ViewInputs
from .props import volume_prop


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
        self._replace_props(renderer, [self.volume])

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
        return REDRAW if change == "background" else IGNORE

    def status(self) -> str:
        step = self.stats.get("sample_distance_mm")
        return f"sample step {step:.2f} mm" if step else ""
