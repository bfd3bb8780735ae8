"""Surface modes: a volume (or a field) at an isovalue -> a triangle surface, by a VTK filter, and the view content
that shows it.

Ours: marching cubes with Bourke's tables (source 001; Lorensen & Cline 1987), the visible voxel faces and the
tower strips of source 000 and their hybrid. VTK's: ``vtkFlyingEdges3D`` and ``vtkMarchingCubes``. Each mode says
which filter to build; :meth:`SurfaceMode.extract` runs it (image -> filter -> surface in the volume frame), for a
view (:class:`SurfaceContent`), for ``voxelscope mesh`` and for comparisons alike, so the window, the command line
and the files agree.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, get_numpy_array_type
from vtkmodules.vtkCommonDataModel import vtkImageData

from algorithms.common.progress import report, scaled
from algorithms.common.vtk_bridge import image_from_array, run_algorithm
from algorithms.surfaces import tower, voxel_faces
from algorithms.surfaces.marching_cubes import MarchingCubesFilter, count_triangles

from ..cutaways import cut_for_surface
from ..pipeline.content import IGNORE, REBUILD, ViewInputs
from ..pipeline.lit_surfaces import LitContent, SurfaceResult, format_bytes, polydata_stats
from ..pipeline.props import surface_actor, surface_color
from . import register_mode
from .base import Capabilities, Mode, Option


@dataclass(frozen=True)
class SurfaceMode(Mode):
    """An isosurface mode. ``make_filter(options, iso, stride)`` returns the configured VTK algorithm (image in,
    polydata out); ``compiled`` marks numba filters (warmed up on a tiny volume first, so ``seconds`` measures the
    extraction and ``compile_seconds`` the compilation or cache load); ``statistics(polydata)`` adds method-specific
    numbers (strip memory of the voxel surfaces)."""

    make_filter: Callable[..., Any] | None = None
    flat_shading: bool = False
    compiled: bool = False
    statistics: Callable[[Any], dict] | None = None
    #: ``count(array, iso, stride, progress)``: the number of triangles the filter will make, found without
    #: extracting; ``bound(shape)``: the most the filter can make on a grid of that shape (the count is skipped
    #: when that is below the limit asked about).
    count: Callable[..., int] | None = None
    bound: Callable[[tuple[int, ...]], int] | None = None
    #: The filter never puts two points at one position (exports then skip merging coincident points).
    unique_points: bool = False

    def create_content(self, options: Mapping[str, Any]) -> "SurfaceContent":
        return SurfaceContent(self, options)

    def extract(self, item, iso: float, *, stride: int = 1, options: Mapping[str, Any] | None = None,
                progress=None) -> SurfaceResult:
        """The surface of ``item`` (a scene item or a :class:`~app.volume.Volume`) at ``iso``, volume frame (mm).

        ``stride`` > 1 uses the mode's coarse path (every ``stride``-th sample); a mode without one refuses.
        """
        if not np.isfinite(iso):
            raise ValueError(f"the isovalue must be a finite number, got {iso}")
        if int(stride) != stride or stride < 1:
            raise ValueError(f"the stride must be a whole number of voxels, 1 or more; got {stride}")
        if stride > 1 and not self.capabilities.preview_stride:
            raise ValueError(f"{self.label} extracts at full resolution only (stride 1)")
        options = self.resolve_options(options)
        image = item.vtk_image() if hasattr(item, "vtk_image") else shared_image(item)
        compile_seconds = _warm_up(self, options, image) if self.compiled else 0.0
        algorithm = self.make_filter(options, float(iso), int(stride))
        algorithm.SetInputDataObject(image)
        start = time.perf_counter()
        output = run_algorithm(algorithm, progress)
        seconds = time.perf_counter() - start
        polydata = output.NewInstance()
        polydata.ShallowCopy(output)
        stats = polydata_stats(polydata)
        if self.statistics is not None:
            stats.update(self.statistics(polydata))
        stats.update({"seconds": seconds, "compile_seconds": compile_seconds})
        return SurfaceResult(polydata, stats)

    def estimate_triangles(self, item, iso: float, *, stride: int = 1, limit: int | None = None,
                           progress=None) -> int | None:
        """How many triangles :meth:`extract` will make for ``item`` at ``iso``, without extracting: None when the
        mode cannot count, or when ``limit`` is given and the mode cannot make more than that on this grid."""
        if self.count is None:
            return None
        array = item.volume.array if hasattr(item, "volume") else item.array
        if limit is not None and self.bound is not None:
            shape = tuple(-(-n // stride) for n in array.shape)
            if self.bound(shape) <= limit:
                return None
        return int(self.count(array, float(iso), int(stride), progress))


class SurfaceContent(LitContent):
    """An isosurface of the item at the view's isovalue, extracted by the mode's filter."""

    result: SurfaceResult | None = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None) -> SurfaceResult:
        stride = self.mode.capabilities.preview_stride if preview else 0
        tools = inputs.visible_tools() if self.mode.capabilities.accepts_cutaways else []
        if not tools:
            return self.mode.extract(inputs.item, inputs.iso, stride=max(stride, 1), options=self.options,
                                     progress=progress)
        # The surface of the data minus the tools, capped at the cut (the CSG difference of source 002, 3.3.1).
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
        if change == "cutaways":
            return REBUILD if self.mode.capabilities.accepts_cutaways else IGNORE
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


def shared_image(volume):
    """A ``vtkImageData`` of a :class:`~app.volume.Volume` in its volume frame (origin 0, identity direction) on the
    volume's own memory: extracting the surface of a large volume does not hold its samples twice."""
    array = np.ascontiguousarray(volume.array)
    nz, ny, nx = array.shape
    image = vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetSpacing(*map(float, volume.spacing))
    scalars = numpy_to_vtk(array.reshape(-1), deep=False)
    scalars.SetName("scalars")
    image.GetPointData().SetScalars(scalars)
    return image


_WARM: set[tuple[str, str]] = set()


def _warm_up(mode: SurfaceMode, options, image) -> float:
    """Run ``mode``'s filter once on a tiny volume of the image's type so numba compiles (or loads its cache) before
    the timed run; returns the seconds it took (0 once warm)."""
    scalars = image.GetPointData().GetScalars()
    dtype = np.dtype(get_numpy_array_type(scalars.GetDataType()) if scalars is not None else np.float32).name
    key = (mode.name, dtype)
    if key in _WARM:
        return 0.0
    start = time.perf_counter()
    tiny = np.zeros((3, 3, 3), dtype=dtype)
    tiny[1, 1, 1] = 1
    algorithm = mode.make_filter(options, 0.5, 1)
    algorithm.SetInputDataObject(image_from_array(tiny))
    run_algorithm(algorithm)
    _WARM.add(key)
    return time.perf_counter() - start


# ----------------------------------------------------------------------------------------------------------------
# The filters
# ----------------------------------------------------------------------------------------------------------------
def _vtk_contour(class_name: str):
    def make(options, iso: float, stride: int):
        import vtkmodules.vtkFiltersCore as core

        algorithm = getattr(core, class_name)()
        algorithm.SetValue(0, iso)
        algorithm.SetComputeNormals(1)
        algorithm.SetComputeScalars(0)
        if hasattr(algorithm, "SetComputeGradients"):
            algorithm.SetComputeGradients(0)
        return algorithm

    return make


def _marching_cubes(options, iso: float, stride: int):
    algorithm = MarchingCubesFilter()
    algorithm.SetValue(0, iso)
    algorithm.SetStride(stride)
    algorithm.ComputeNormalsOn()
    return algorithm


def _voxel_filter(class_name: str):
    def make(options, iso: float, stride: int):
        module = voxel_faces if class_name == "VoxelFacesFilter" else tower
        algorithm = getattr(module, class_name)()
        algorithm.SetThreshold(iso)
        if "max_strip_vertices" in options:
            algorithm.SetMaxStripVertices(options["max_strip_vertices"])
        return algorithm

    return make


def _marching_cubes_count(array, iso: float, stride: int, progress) -> int:
    """Our marching cubes' counting pass: exact for ours, within the ambiguous cells for VTK's case table."""
    return count_triangles(array, iso, stride=stride, progress=progress)


def _cell_bound(shape) -> int:
    """At most 5 triangles per cell (the largest case of the marching-cubes tables)."""
    cells = int(np.prod([max(n - 1, 0) for n in shape]))
    return 5 * cells


def _visible_face_count(array, iso: float, stride: int, progress) -> int:
    """Two triangles per visible voxel face (voxels at or above ``iso``; outside the volume counts as empty),
    counted slab by slab so no array of the volume's size is made."""
    if stride != 1:
        raise ValueError("voxel surfaces are extracted at full resolution only (stride 1)")
    nz = array.shape[0]
    faces = 0
    below = None
    step = max(1, 4_000_000 // max(array.shape[1] * array.shape[2], 1))
    for start in range(0, nz, step):
        solid = array[start:start + step] >= iso
        faces += int(np.count_nonzero(solid[:, :, 1:] != solid[:, :, :-1]))
        faces += int(np.count_nonzero(solid[:, :, 0])) + int(np.count_nonzero(solid[:, :, -1]))
        faces += int(np.count_nonzero(solid[:, 1:, :] != solid[:, :-1, :]))
        faces += int(np.count_nonzero(solid[:, 0, :])) + int(np.count_nonzero(solid[:, -1, :]))
        faces += int(np.count_nonzero(solid[1:] != solid[:-1]))
        faces += int(np.count_nonzero(solid[0] != below)) if below is not None else int(np.count_nonzero(solid[0]))
        below = solid[-1].copy()
        report(progress, min(1.0, (start + step) / nz))
    faces += int(np.count_nonzero(below))
    return 2 * faces


def _voxel_bound(shape) -> int:
    """Each voxel has six faces of two triangles; between two voxels at most one of them is visible."""
    nz, ny, nx = shape
    return 2 * ((nx + 1) * ny * nz + nx * (ny + 1) * nz + nx * ny * (nz + 1))


def _voxel_memory(polydata) -> dict:
    """The voxel surfaces' memory as source 000 counts it (strips without indices) and as VTK uploads it."""
    from algorithms.compare.voxel_surfaces import polydata_memory

    memory = polydata_memory(polydata)
    return {
        "bytes": memory.total_bytes(32),
        "bytes_16": memory.total_bytes(16),
        "vertices": memory.vertices,
        "indices": memory.indices,
        "draw_calls": memory.draw_calls,
        "vtk_upload_bytes": memory.vtk_upload_bytes,
    }


SURFACE = dict(group="Surfaces", input="volume", output="surface")
ISO = Capabilities(uses_iso=True, accepts_cutaways=True)

MARCHING_COUNT = dict(count=_marching_cubes_count, bound=_cell_bound)
VOXEL_COUNT = dict(count=_visible_face_count, bound=_voxel_bound)

register_mode(SurfaceMode(
    "marching-cubes", "Marching cubes", "Our marching cubes with Paul Bourke's case tables, shared edge vertices and "
    "gradient normals (source 001)", origin="ours", **SURFACE, make_filter=_marching_cubes, compiled=True,
    capabilities=Capabilities(uses_iso=True, preview_stride=2, accepts_cutaways=True), unique_points=True, **MARCHING_COUNT,
))
register_mode(SurfaceMode(
    "flying-edges", "Flying edges", "Isosurface by VTK's vtkFlyingEdges3D (parallel, with gradient normals)",
    origin="VTK", **SURFACE, make_filter=_vtk_contour("vtkFlyingEdges3D"), capabilities=ISO, **MARCHING_COUNT,
))
register_mode(SurfaceMode(
    "vtk-marching-cubes", "Marching cubes", "Isosurface by VTK's classic vtkMarchingCubes (with gradient normals)",
    origin="VTK", **SURFACE, make_filter=_vtk_contour("vtkMarchingCubes"), capabilities=ISO, **MARCHING_COUNT,
))
register_mode(SurfaceMode(
    "voxel-faces", "Voxel faces", "Every visible face of the voxels at or above the threshold, 4 vertices and "
    "6 indices each (source 000)", origin="ours", **SURFACE, make_filter=_voxel_filter("VoxelFacesFilter"),
    flat_shading=True, compiled=True, statistics=_voxel_memory, capabilities=ISO, **VOXEL_COUNT,
))
register_mode(SurfaceMode(
    "tower", "Tower strips", "The same faces as triangle strips: one per cluster boundary and slice, plus top and "
    "bottom runs (source 000's tower algorithm)", origin="ours", **SURFACE, make_filter=_voxel_filter("TowerFilter"),
    flat_shading=True, compiled=True, statistics=_voxel_memory, capabilities=ISO, **VOXEL_COUNT,
))
register_mode(SurfaceMode(
    "hybrid", "Hybrid strips", "Tower strips, with strips of at most L vertices turned back into indexed triangles "
    "(source 000)", origin="ours", **SURFACE, make_filter=_voxel_filter("HybridFilter"), flat_shading=True,
    compiled=True, statistics=_voxel_memory, capabilities=ISO, **VOXEL_COUNT,
    options=(Option("max_strip_vertices", "int", 10, "hybrid: strips of at most this many vertices become "
                    "indexed triangles (source 000 used 10)", minimum=4, maximum=1_000_000),),
))
