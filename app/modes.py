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

import numpy as np

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


@dataclass(frozen=True)
class CompareMode:
    """Two modes side by side in one view: a surface coloured by its distance to another surface
    (``app.compare.surface_distance``), or the difference of two renderings as a heat map
    (``app.compare.image_difference``)."""

    name: str
    label: str
    description: str
    test: str
    reference: str
    kind: str = "compare"

    @property
    def measure(self) -> str:
        return "surface-distance" if get_mode(self.test).kind == "surface" else "image-difference"

    @property
    def parallel_only(self) -> bool:
        return getattr(get_mode(self.test), "parallel_only", False)


Mode = SurfaceMode | VolumeMode | ImageMode | CompareMode
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
    """Registered mode names, optionally of one kind (``surface``, ``volume``, ``image``, ``compare``)."""
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
    register_mode(SurfaceMode(
        "marching-cubes", "Marching cubes (ours)",
        "Our marching cubes with Paul Bourke's case tables, shared edge vertices and gradient normals (source 001)",
        _extract_marching_cubes, supports_step=True,
    ))
    register_mode(SurfaceMode(
        "voxel-faces", "Voxel faces (ours)",
        "Every visible face of the voxels at or above the threshold, 4 vertices and 6 indices each (source 000)",
        _voxel_surface("voxel-faces"), flat_shading=True,
    ))
    register_mode(SurfaceMode(
        "tower", "Tower strips (ours)",
        "The same faces as triangle strips: one per cluster boundary and slice, plus top and bottom runs "
        "(source 000's tower algorithm)", _voxel_surface("tower"), flat_shading=True,
    ))
    register_mode(SurfaceMode(
        "hybrid", "Hybrid strips (ours)",
        "Tower strips, with strips of at most 10 vertices turned back into indexed triangles (source 000)",
        _voxel_surface("hybrid"), flat_shading=True,
    ))
    register_mode(VolumeMode(
        "vtk-gpu", "GPU ray casting (VTK)", "VTK's vtkGPUVolumeRayCastMapper (OpenGL; Mesa llvmpipe without a GPU)", "gpu",
    ))
    register_mode(VolumeMode(
        "vtk-cpu", "CPU ray casting (VTK)", "VTK's vtkFixedPointVolumeRayCastMapper (multi-threaded CPU)", "cpu",
    ))
    register_mode(ImageMode(
        "raymarch", "Ray marching (ours)",
        "Our ray marcher: Beer-Lambert absorption, Blinn-Phong or single scattering, early termination, "
        "empty-space skipping", _create_raymarch, options=("step", "lighting", "samples", "light_samples"),
    ))
    register_mode(ImageMode(
        "slicing", "Texture slicing (ours)",
        "View-aligned slices blended back to front (float compositing; --compositing gl draws them with OpenGL)",
        _slicing_factory("view"), options=("step", "slices", "compositing"),
    ))
    register_mode(ImageMode(
        "slicing-axis", "Axis-aligned slicing (ours)",
        "Three stacks of axis-aligned slices, the one most perpendicular to the view drawn back to front",
        _slicing_factory("axis"), options=("compositing",),
    ))
    register_mode(ImageMode(
        "shear-warp", "Shear-warp (ours)",
        "Lacroute's shear-warp factorisation with run-length encoded volume and image, early termination "
        "(parallel projection)", _create_shear_warp, parallel_only=True, options=("step",),
    ))
    register_mode(CompareMode(
        "marching-cubes-vs-flying-edges", "Distance: marching cubes to flying edges",
        "Our marching-cubes surface coloured by its distance (mm) to VTK's flying-edges surface",
        "marching-cubes", "flying-edges",
    ))
    for test in ("raymarch", "slicing", "shear-warp"):
        register_mode(CompareMode(
            f"{test}-vs-vtk-gpu", f"|{get_mode(test).label.split(' (')[0]} - GPU ray casting|",
            f"Heat map of the difference between {test} and vtk-gpu at the same camera, with PSNR, RMSE and SSIM",
            test, "vtk-gpu",
        ))


def _warm_up(function, dtype, **options) -> float:
    """Run ``function`` once on a tiny volume of ``dtype`` so numba compiles (or loads from its cache) before the
    timed run; returns the seconds it took. Extraction times then measure the extraction alone."""
    start = time.perf_counter()
    tiny = np.zeros((3, 3, 3), dtype=dtype)
    tiny[1, 1, 1] = 1
    function(tiny, 0.5, **options)
    return time.perf_counter() - start


def _extract_marching_cubes(volume: Volume, iso: float, *, step: int = 1,
                            progress: ProgressCallback = None) -> SurfaceResult:
    """Our marching cubes with Bourke's tables (source 001), gradient normals, one vertex per cut edge."""
    from algorithms.marching_cubes import marching_cubes

    compile_seconds = _warm_up(marching_cubes, volume.array.dtype, normals=True)
    start = time.perf_counter()
    mesh = marching_cubes(volume.array, iso, spacing=volume.spacing, step=step, normals=True, progress=progress)
    seconds = time.perf_counter() - start
    polydata = mesh.to_polydata()
    stats = polydata_stats(polydata)
    stats.update({"seconds": seconds, "compile_seconds": compile_seconds})
    return SurfaceResult(polydata, stats)


def _voxel_surface(kind: str):
    """Visible voxel faces (source 000): the indexed baseline, the tower strips, or the hybrid of both."""

    def extract(volume: Volume, iso: float, *, step: int = 1, progress: ProgressCallback = None) -> SurfaceResult:
        from algorithms.tower import hybrid, tower_strips
        from algorithms.voxel_faces import voxel_faces
        from algorithms.voxel_surface_checks import memory_usage

        if step != 1:
            raise ValueError("voxel-face surfaces are drawn at full resolution only (step 1)")
        builder = {"voxel-faces": voxel_faces, "tower": tower_strips, "hybrid": hybrid}[kind]
        compile_seconds = _warm_up(lambda array, level: builder(array, threshold=level), volume.array.dtype)
        start = time.perf_counter()
        surface = builder(volume.array, threshold=iso, spacing=volume.spacing, progress=progress)
        seconds = time.perf_counter() - start
        polydata = surface.to_polydata()
        memory = memory_usage(surface)
        stats = polydata_stats(polydata)
        stats.update({
            "bytes": memory.total_bytes(32),
            "bytes_16": memory.total_bytes(16),
            "vertices": memory.vertices,
            "indices": memory.indices,
            "draw_calls": memory.draw_calls,
            "vtk_upload_bytes": memory.vtk_upload_bytes,
            "seconds": seconds,
            "compile_seconds": compile_seconds,
        })
        return SurfaceResult(polydata, stats)

    return extract


def _table(volume: Volume, transfer_function):
    return transfer_function.to_table(volume.value_range)


def _create_raymarch(volume: Volume, transfer_function, options: Mapping[str, Any]):
    """Our ray marcher (source 001 technique 2, source 002 2.3-2.4); lighting defaults to the preset's shading."""
    from algorithms.raymarch import RaymarchRenderer, step_for_samples

    step = options.get("step")
    if options.get("samples"):
        if step is not None:
            raise ValueError("give either a sample step (--step) or a number of samples (--samples), not both")
        step = step_for_samples(volume.array.shape, volume.spacing, int(options["samples"]))
    shading = transfer_function.shading
    lighting = options.get("lighting") or ("phong" if shading.enabled else "emission")
    return RaymarchRenderer(
        volume.array, volume.spacing, _table(volume, transfer_function), step=step, lighting=lighting,
        light_samples=int(options.get("light_samples") or 8), ambient=shading.ambient, diffuse=shading.diffuse,
        specular=shading.specular, specular_power=shading.specular_power,
    )


def _slicing_factory(mode: str):
    def create(volume: Volume, transfer_function, options: Mapping[str, Any]):
        """Texture slicing (source 001 technique 3, source 002 2.4.2-2.4.3), composited in float or 8 bits."""
        from algorithms.texture_slicing import SlicingRenderer

        precision = options.get("compositing") or "float"
        if precision not in ("float", "uint8"):
            raise ValueError(f"software slicing composites in 'float' or 'uint8', got {precision!r}")
        extra = {}
        if mode == "view":
            if options.get("slices") and options.get("step") is not None:
                raise ValueError("give either a number of slices (--slices) or a slice distance (--step), not both")
            if options.get("slices"):
                extra["slices"] = int(options["slices"])
            elif options.get("step") is not None:
                extra["step"] = float(options["step"])
        elif options.get("slices") or options.get("step") is not None:
            raise ValueError("axis-aligned slices are the voxel layers; --slices and --step apply to 'slicing' only")
        return SlicingRenderer(volume.array, volume.spacing, _table(volume, transfer_function), mode=mode,
                               precision=precision, **extra)

    return create


def _create_shear_warp(volume: Volume, transfer_function, options: Mapping[str, Any]):
    """Shear-warp (source 004): run-length encoded volume and image, early termination; parallel projection."""
    from algorithms.shear_warp import ShearWarpRenderer

    shading = transfer_function.shading
    return ShearWarpRenderer(
        volume.array, volume.spacing, _table(volume, transfer_function), step=options.get("step"),
        shading=shading.enabled, ambient=shading.ambient, diffuse=shading.diffuse, specular=shading.specular,
        specular_power=shading.specular_power,
    )


_registered = False


def _ensure_registered() -> None:
    global _registered
    if not _registered:
        _registered = True
        _register_builtin_modes()
