"""Surface contents: an isosurface extracted from a volume by a VTK filter (ours or VTK's), and a mesh of the
scene shown as it is.

The extraction itself is the mode's (:meth:`app.modes.surfaces.SurfaceMode.extract`): reader output -> the mode's
filter -> a surface in the volume frame. Mesh export and comparisons call the same extraction, so the window, the
command line and the files agree.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .content import IGNORE, REBUILD, REDRAW, ViewContent, ViewInputs
from .props import SurfaceLighting, surface_actor, surface_color

VERTEX_BYTES = 12  # 3 x float32
INDEX_BYTES = 4  # 32-bit indices


@dataclass
class SurfaceResult:
    """A surface in the volume frame (mm) and its statistics.

    ``stats`` holds at least ``points``, ``triangles``, ``cells``, ``strips``, ``bytes`` (vertex plus index bytes of
    the representation) and ``seconds`` (extraction only, without numba's compilation: ``compile_seconds``).
    """

    polydata: Any
    stats: dict[str, Any] = field(default_factory=dict)


def polydata_stats(polydata) -> dict[str, int]:
    """Points, triangles (strips expanded), cells, strips and bytes of an indexed representation.

    Bytes count what a renderer keeps in GPU buffers for this representation: 3 x float32 per point plus one
    32-bit index per connectivity entry of polygons and strips. Methods with their own accounting (the tower
    algorithm stores strips without indices, as its source does) override ``bytes`` in their own statistics.
    """
    from vtkmodules.util import numpy_support

    triangles = connectivity = strip_count = 0
    for cells, is_strips in ((polydata.GetPolys(), False), (polydata.GetStrips(), True)):
        if cells is None or not cells.GetNumberOfCells():
            continue
        offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray())
        sizes = offsets[1:] - offsets[:-1]
        triangles += int((sizes - 2).clip(min=0).sum())
        connectivity += int(sizes.sum())
        if is_strips:
            strip_count = int(cells.GetNumberOfCells())
    points = int(polydata.GetNumberOfPoints())
    return {
        "points": points,
        "triangles": triangles,
        "cells": int(polydata.GetNumberOfCells()),
        "strips": strip_count,
        "bytes": points * VERTEX_BYTES + connectivity * INDEX_BYTES,
    }


def format_bytes(count: float) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if count < 1024 or unit == "GB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024.0
    return f"{count:.1f} GB"


class LitContent(ViewContent):
    """A content showing surfaces: it lights the renderer with :data:`~app.pipeline.props.SURFACE_LIGHTS` while its
    props are on it, so every surface mode is lit the same way."""

    lighting: SurfaceLighting | None = None

    def _replace_props(self, renderer, props: list, detail_mm: float = 1.0) -> None:
        super()._replace_props(renderer, props)
        if self.lighting is None:
            self.lighting = SurfaceLighting()
        self.lighting.install(renderer, detail_mm)

    def remove(self, renderer) -> None:
        super().remove(renderer)
        if self.lighting is not None:
            self.lighting.remove()


class SurfaceContent(LitContent):
    """An isosurface of the item at the view's isovalue, extracted by the mode's filter."""

    result: SurfaceResult | None = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None) -> SurfaceResult:
        stride = self.mode.capabilities.preview_stride if preview else 0
        tools = inputs.visible_tools() if self.mode.capabilities.accepts_selection else []
        if not tools:
            return self.mode.extract(inputs.item, inputs.iso, stride=max(stride, 1), options=self.options,
                                     progress=progress)
        # The surface of the data minus the tools, capped at the cut (the CSG difference of source 002, 3.3.1).
        import time

        from algorithms.common.progress import scaled

        from ..selection import cut_for_surface

        start = time.perf_counter()
        source = cut_for_surface(inputs.volume, tools, inputs.iso, evaluation=inputs.cut_evaluation,
                                 progress=scaled(progress, 0.0, 0.3))
        cut_seconds = time.perf_counter() - start
        result = self.mode.extract(source, inputs.iso, stride=max(stride, 1), options=self.options,
                                   progress=scaled(progress, 0.3, 1.0))
        result.stats["cut_seconds"] = cut_seconds
        result.stats["tools"] = len(tools)
        return result

    def install(self, renderer, inputs: ViewInputs, prepared: SurfaceResult) -> None:
        self.result = prepared
        self.stats = dict(prepared.stats)
        volume = inputs.volume
        lo, hi = volume.value_range
        self._iso, self._units, self._range = inputs.iso, volume.units_label, f"{lo:g} to {hi:g} {volume.units_label}"
        units = getattr(volume, "units", "")
        actor = surface_actor(prepared.polydata, inputs.item.local_to_world, color=surface_color(units, inputs.iso),
                              flat=self.mode.flat_shading)
        self._replace_props(renderer, [actor], detail_mm=max(volume.spacing))

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if change == "selection":
            return REBUILD if self.mode.capabilities.accepts_selection else IGNORE
        return REBUILD if change == "iso" else IGNORE

    def status(self) -> str:
        s = self.stats
        if not s:
            return ""
        if not s["triangles"]:
            return f"no surface at {self._iso:g} {self._units} (the values run from {self._range})"
        return (f"{s['points']:,} points, {s['triangles']:,} triangles, {s['strips']:,} strips, "
                f"{format_bytes(s['bytes'])}, built in {s['seconds']:.2f} s")

    def surface(self) -> SurfaceResult | None:
        return self.result


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
