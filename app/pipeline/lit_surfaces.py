"""What every content showing a surface shares: the surface result (a ``vtkPolyData`` and its statistics), the
statistics of an indexed representation, and the lighting every surface mode is lit with (:class:`LitContent`).

The surface modes themselves (extraction by our filters or VTK's, meshes of the scene, comparisons by distance) are
families of :mod:`app.modes`; mesh export (:mod:`app.meshing`) uses the same result type.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from vtkmodules.util import numpy_support

from .content import ViewContent
from .props import SurfaceLighting

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
