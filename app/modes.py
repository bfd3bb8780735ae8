"""The render-mode registry: every way Voxelscope can show a volume, by name.

Three kinds of mode, and what each provides:

``surface``
    ``extract(volume, iso, *, step=1, progress=None) -> SurfaceResult``: a ``vtkPolyData`` in the volume frame
    plus statistics. Used by ``voxelscope mesh``, ``voxelscope render`` and the workbench's surface views.
``volume``
    A VTK volume mapper (``vtk-gpu``, ``vtk-cpu``) built by :func:`app.rendering.volume_prop`.
``image``
    One of our software renderers: ``create(volume, transfer_function, options) -> renderer`` whose
    ``render(camera_in_volume_frame, width, height, *, progress=None)`` returns an
    :class:`algorithms.render_result.RenderResult`. The workbench shows the image in the view; the command
    line writes it as a PNG.

Algorithm modules register their modes here (in :func:`_register_builtin_modes`), so the command line and the
window never need to change when a mode is added.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

from algorithms._progress import ProgressCallback

from .volume import Volume


@dataclass
class SurfaceResult:
    """A surface in the volume frame (mm) and its statistics.

    ``stats`` holds at least ``points``, ``triangles``, ``cells``, ``strips``, ``bytes`` (vertex plus index bytes of
    the representation) and ``seconds`` (extraction only).
    """

    polydata: Any
    stats: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class SurfaceMode:
    name: str
    label: str
    description: str
    extract: Callable[..., SurfaceResult]
    flat_shading: bool = False
    supports_step: bool = False
    kind: str = "surface"


@dataclass(frozen=True)
class VolumeMode:
    name: str
    label: str
    description: str
    mapper: str
    kind: str = "volume"


@dataclass(frozen=True)
class ImageMode:
    name: str
    label: str
    description: str
    create: Callable[[Volume, Any, Mapping[str, Any]], Any]
    parallel_only: bool = False
    options: tuple[str, ...] = ()
    kind: str = "image"


Mode = SurfaceMode | VolumeMode | ImageMode
_MODES: dict[str, Mode] = {}


def register_mode(mode: Mode) -> Mode:
    """Add a mode (a name may be registered once)."""
    if mode.name in _MODES:
        raise ValueError(f"a render mode named {mode.name!r} is already registered")
    _MODES[mode.name] = mode
    return mode


def get_mode(name: str) -> Mode:
    """The mode called ``name``; a ValueError lists the choices otherwise."""
    _ensure_registered()
    try:
        return _MODES[name]
    except KeyError:
        raise ValueError(f"unknown mode {name!r}; choose one of {', '.join(mode_names())}") from None


def mode_names(kind: str | None = None) -> list[str]:
    """Registered mode names, optionally of one kind (``surface``, ``volume``, ``image``)."""
    _ensure_registered()
    return [name for name, mode in _MODES.items() if kind is None or mode.kind == kind]


# ------------------------------------------------------------------------------------------------------------
# Statistics shared by every surface method
# ------------------------------------------------------------------------------------------------------------
VERTEX_BYTES = 12  # 3 x float32
INDEX_BYTES = 4  # 32-bit indices


def polydata_stats(polydata) -> dict[str, float]:
    """Points, triangles (strips expanded), cells, strips and bytes of an indexed representation.

    Bytes count what a renderer keeps in GPU buffers for this representation: 3 x float32 per point plus one
    32-bit index per connectivity entry of polygons and strips. Methods with their own accounting (the tower
    algorithm stores strips without indices, as its source does) override ``bytes`` in their own statistics.
    """
    from vtkmodules.util import numpy_support

    polys, strips = polydata.GetPolys(), polydata.GetStrips()
    triangles = 0
    connectivity = 0
    if polys is not None and polys.GetNumberOfCells():
        sizes = numpy_support.vtk_to_numpy(polys.GetOffsetsArray())
        sizes = sizes[1:] - sizes[:-1]
        triangles += int((sizes - 2).clip(min=0).sum())
        connectivity += int(sizes.sum())
    strip_count = 0
    if strips is not None and strips.GetNumberOfCells():
        sizes = numpy_support.vtk_to_numpy(strips.GetOffsetsArray())
        sizes = sizes[1:] - sizes[:-1]
        triangles += int((sizes - 2).clip(min=0).sum())
        connectivity += int(sizes.sum())
        strip_count = int(strips.GetNumberOfCells())
    points = int(polydata.GetNumberOfPoints())
    return {
        "points": points,
        "triangles": triangles,
        "cells": int(polydata.GetNumberOfCells()),
        "strips": strip_count,
        "bytes": points * VERTEX_BYTES + connectivity * INDEX_BYTES,
    }


# ------------------------------------------------------------------------------------------------------------
# VTK's built-in surface extractors
# ------------------------------------------------------------------------------------------------------------
def _vtk_contour(algorithm_class, *, normals: bool):
    def extract(volume: Volume, iso: float, *, step: int = 1, progress: ProgressCallback = None) -> SurfaceResult:
        from algorithms._vtk import run_algorithm

        if step != 1:
            raise ValueError(f"{algorithm_class.__name__} extracts at full resolution only (step 1)")
        image = volume.to_vtk(local=True)
        algorithm = algorithm_class()
        algorithm.SetInputData(image)
        algorithm.SetValue(0, float(iso))
        algorithm.SetComputeNormals(int(normals))
        algorithm.SetComputeScalars(0)
        if hasattr(algorithm, "SetComputeGradients"):
            algorithm.SetComputeGradients(0)
        start = time.perf_counter()
        output = run_algorithm(algorithm, progress)
        seconds = time.perf_counter() - start
        polydata = output.NewInstance()
        polydata.ShallowCopy(output)
        stats = polydata_stats(polydata)
        stats["seconds"] = seconds
        return SurfaceResult(polydata, stats)

    return extract


def _register_builtin_modes() -> None:
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D, vtkMarchingCubes

    register_mode(SurfaceMode(
        "flying-edges", "Flying edges (VTK)",
        "Isosurface by VTK's vtkFlyingEdges3D (parallel, with gradient normals)",
        _vtk_contour(vtkFlyingEdges3D, normals=True),
    ))
    register_mode(SurfaceMode(
        "vtk-marching-cubes", "Marching cubes (VTK)",
        "Isosurface by VTK's classic vtkMarchingCubes (with gradient normals)",
        _vtk_contour(vtkMarchingCubes, normals=True),
    ))
    register_mode(VolumeMode(
        "vtk-gpu", "GPU ray casting (VTK)", "VTK's vtkGPUVolumeRayCastMapper (OpenGL; Mesa llvmpipe without a GPU)", "gpu",
    ))
    register_mode(VolumeMode(
        "vtk-cpu", "CPU ray casting (VTK)", "VTK's vtkFixedPointVolumeRayCastMapper (multi-threaded CPU)", "cpu",
    ))


_registered = False


def _ensure_registered() -> None:
    global _registered
    if not _registered:
        _registered = True
        _register_builtin_modes()
