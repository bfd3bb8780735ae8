"""Tetrahedral-mesh modes: a volume's (or field's) isosurface filled with tetrahedra, shown cut open by a plane and
coloured by each tetrahedron's smallest dihedral angle, with the angle histogram in the view.

Ours: ``stuffing`` (isosurface stuffing, Labelle & Shewchuk 2007; source 002, chapter 4). VTK's: ``vtk-delaunay``
(``vtkDelaunay3D`` on the isosurface's points, the tetrahedra outside removed) and ``vtk-clip-tets``
(``vtkClipVolume``, tetrahedra only). ``stuffing-vs-vtk-clip-tets`` and ``stuffing-vs-vtk-delaunay`` show ours
beside VTK's with both histograms; ``tetmesh`` shows a tetrahedral mesh of the scene.

In a view the tetrahedra are cut open by a plane so the interior shows, coloured by each tetrahedron's smallest
dihedral angle, with the angle histogram drawn in a corner of the view and the numbers in the status line
(:class:`TetMeshContent`; :class:`TetComparisonContent` puts two methods side by side, the reference moved beside
ours along x, each with its histogram).

The clip plane is a mode option (``clip_origin``, ``clip_normal``: "x y z" in LPS mm; an empty origin is the
mesh's centre), so ``voxelscope render --mode stuffing`` draws clipped views too; the window's plane widget
(:mod:`ui.clip_plane`) moves it with :meth:`TetMeshContent.set_clip_plane` while dragging and writes it back
through the view's options when the drag ends. Meshes are cached by item, method and parameters, so a new plane
only clips again.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPlane, vtkImageData

from algorithms.common.mesh import TetMesh
from algorithms.common.progress import scaled

from ..operations.tetrahedra import TetResult, tetrahedralise
from ..pipeline.content import IGNORE, REBUILD, REDRAW, ViewContent, ViewInputs
from . import get_mode, register_mode
from .base import Capabilities, Mode, Option

CLIP_OPTIONS = (
    Option("clip", "bool", True, "tetrahedra: cut the mesh open with a plane (whole tetrahedra on one side stay)"),
    Option("clip_origin", "str", "", "tetrahedra: a point of the clip plane, 'x y z' in LPS mm (default: the mesh's "
           "centre)"),
    Option("clip_normal", "str", "0 -1 0", "tetrahedra: the clip plane's normal 'x y z' (LPS); the tetrahedra on its "
           "negative side stay (default: the posterior half, cut face towards an anterior camera)"),
)
STUFFING_OPTIONS = (
    Option("h", "float", None, "stuffing: lattice spacing (default twice the smallest voxel spacing)", unit="mm",
           minimum=0.01, maximum=1000.0),
    Option("alpha", "str", "10.7", "stuffing: the paper's parameter pair, by its lower angle bound (10.7: angles in "
           "[10.7, 164.8] degrees; 8.9: in [8.9, 158.8])", choices=("10.7", "8.9")),
)
CLIPS = Capabilities(uses_iso=True, clip_plane=True)


@dataclass(frozen=True)
class TetMode(Mode):
    """A tetrahedralisation shown clipped; ``method`` names it for :func:`app.operations.tetrahedra.tetrahedralise`
    (``"item"`` shows a tetrahedral mesh of the scene)."""

    method: str = "stuffing"

    def create_content(self, options: Mapping[str, Any]) -> "TetMeshContent":
        return TetMeshContent(self, options)

    def check_options(self, options: Mapping[str, Any]) -> None:
        clip_plane(options, (0, 0, 0, 0, 0, 0))  # refuses malformed planes before any work


@dataclass(frozen=True)
class TetComparisonMode(TetMode):
    """Ours (``test``) beside a reference (``reference``): the modes themselves."""

    test: Mode | None = None
    reference: Mode | None = None

    def create_content(self, options: Mapping[str, Any]) -> "TetComparisonContent":
        return TetComparisonContent(self, options)


MIN_ANGLE_ARRAY = "min_dihedral_deg"
#: The default clip plane's normal: the posterior half stays, so the default (anterior) camera looks at the cut.
DEFAULT_NORMAL = "0 -1 0"
#: Meshes up to this many tetrahedra are drawn with their edges.
EDGES_UP_TO = 300_000
#: Colour range of the smallest dihedral angle (degrees): red at 0, yellow at 20, green from 40.
ANGLE_RANGE = (0.0, 70.0)
_CACHE: "OrderedDict[tuple, Any]" = OrderedDict()
CACHE_SIZE = 4


def parse_vector(text: str, name: str) -> np.ndarray | None:
    """Three numbers from ``"x y z"`` (commas allowed); None for an empty text."""
    text = (text or "").replace(",", " ").strip()
    if not text:
        return None
    try:
        values = np.array([float(v) for v in text.split()], dtype=np.float64)
    except ValueError:
        values = np.empty(0)
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise ValueError(f"--{name.replace('_', '-')} needs three numbers 'x y z' (mm, LPS), got {text!r}")
    return values


def clip_plane(options: Mapping[str, Any], bounds) -> tuple[np.ndarray, np.ndarray] | None:
    """``(origin, unit normal)`` of the clip plane from the mode's options, or None when clipping is off."""
    if not options.get("clip", True):
        return None
    origin = parse_vector(options.get("clip_origin", ""), "clip_origin")
    normal = parse_vector(options.get("clip_normal", "") or DEFAULT_NORMAL, "clip_normal")
    if np.linalg.norm(normal) == 0:
        raise ValueError("--clip-normal must not be the zero vector")
    if origin is None:
        b = np.asarray(bounds, dtype=np.float64)
        origin = 0.5 * (b[0::2] + b[1::2])
    return origin, normal / np.linalg.norm(normal)


def tetrahedra_for(item, method: str, iso: float, options: Mapping[str, Any], progress=None):
    """The :class:`~app.operations.tetrahedra.TetResult` of ``item`` by ``method`` (cached)."""
    if item.kind == "tetmesh":
        from algorithms.compare.tet_quality import min_max_dihedral, quality_report

        key = ("item", id(item), item.grid.GetMTime())
        if key not in _CACHE:
            mesh = TetMesh.from_unstructured_grid(item.grid)
            smallest, _ = min_max_dihedral(mesh.points, mesh.tetrahedra)
            quality = quality_report(mesh.points, mesh.tetrahedra, with_conformity=False)
            _remember(key, TetResult(mesh, None, smallest, quality, {}, dict(item.metadata)))
        return _CACHE[key]
    h = options.get("h") if method == "stuffing" else None
    alpha = options.get("alpha", "10.7") if method == "stuffing" else "10.7"
    key = (id(item), method, float(iso), h, alpha)
    if key not in _CACHE:
        _remember(key, tetrahedralise(item, method=method, iso=iso, h=h, alpha=alpha, progress=progress))
    else:
        _CACHE.move_to_end(key)
    return _CACHE[key]


def _remember(key, value) -> None:
    _CACHE[key] = value
    while len(_CACHE) > CACHE_SIZE:
        _CACHE.popitem(last=False)


def angle_lookup_table():
    from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

    colors = vtkColorTransferFunction()
    colors.AddRGBPoint(0.0, 0.75, 0.05, 0.05)
    colors.AddRGBPoint(10.0, 0.95, 0.35, 0.1)
    colors.AddRGBPoint(20.0, 0.95, 0.85, 0.2)
    colors.AddRGBPoint(40.0, 0.35, 0.75, 0.35)
    colors.AddRGBPoint(70.0, 0.2, 0.55, 0.85)
    return colors


class ClippedTets:
    """The props of one tetrahedral mesh: the whole tetrahedra on the kept side of a plane (so the cut shows
    tetrahedra, not a slice), coloured by their smallest dihedral angle."""

    def __init__(self, grid, plane, offset=(0.0, 0.0, 0.0), scale: float = 1.0, centre=(0.0, 0.0, 0.0)) -> None:
        from vtkmodules.vtkFiltersExtraction import vtkExtractGeometry
        from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

        self.plane = vtkPlane()
        self.extract = vtkExtractGeometry()
        self.extract.SetInputData(grid)
        self.extract.SetImplicitFunction(self.plane)
        self.extract.ExtractInsideOn()
        self.extract.ExtractBoundaryCellsOn()
        self.surface = vtkDataSetSurfaceFilter()
        self.surface.SetInputConnection(self.extract.GetOutputPort())
        mapper = vtkPolyDataMapper()
        mapper.SetInputConnection(self.surface.GetOutputPort())
        mapper.SetScalarModeToUseCellFieldData()
        mapper.SelectColorArray(MIN_ANGLE_ARRAY)
        mapper.SetLookupTable(angle_lookup_table())
        mapper.SetScalarRange(*ANGLE_RANGE)
        mapper.ScalarVisibilityOn()
        self.actor = vtkActor()
        self.actor.SetMapper(mapper)
        self.actor.SetOrigin(*centre)
        self.actor.SetScale(scale)
        self.actor.SetPosition(*offset)
        prop = self.actor.GetProperty()
        if grid.GetNumberOfCells() <= EDGES_UP_TO:
            prop.EdgeVisibilityOn()
            prop.SetEdgeColor(0.15, 0.15, 0.15)
            prop.SetLineWidth(0.5)
        self.set_plane(plane)

    def set_plane(self, plane) -> None:
        if plane is None:
            self.plane.SetOrigin(0.0, 0.0, 0.0)
            self.plane.SetNormal(0.0, 0.0, 1.0)
            self.extract.SetImplicitFunction(None)
            self.extract.ExtractInsideOff()
            self.extract.SetImplicitFunction(_everything())
        else:
            origin, normal = plane
            self.plane.SetOrigin(*origin)
            self.plane.SetNormal(*normal)
            self.extract.SetImplicitFunction(self.plane)
            self.extract.ExtractInsideOn()
        self.extract.Modified()

    def shown_cells(self) -> int:
        self.surface.Update()
        return int(self.extract.GetOutput().GetNumberOfCells())


def _everything():
    """An implicit function negative everywhere (keeps every cell)."""
    plane = vtkPlane()
    plane.SetOrigin(0.0, 0.0, 1e30)
    plane.SetNormal(0.0, 0.0, 1.0)
    return plane


def histogram_actor(result, title: str, corner: str = "left", viewport=(512, 512)):
    """The dihedral-angle histogram of a result as a 2D image actor in a bottom corner of the view."""
    # An off-screen figure of its own (no pyplot: the window's process keeps whatever back end it has).
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from vtkmodules.vtkRenderingCore import vtkActor2D, vtkImageMapper

    histogram = result.quality.get("histogram")
    figure = Figure(figsize=(2.7, 1.5), dpi=80)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    if histogram:
        edges = np.asarray(histogram["edges"])
        axes.bar(edges[:-1], histogram["counts"], width=np.diff(edges), align="edge", color="#4a90d9")
    low = result.quality.get("min_dihedral_deg", float("nan"))
    high = result.quality.get("max_dihedral_deg", float("nan"))
    axes.set_title(f"{title}: {low:.1f}-{high:.1f} degrees", fontsize=8)
    axes.set_xlim(0, 180)
    axes.set_xlabel("dihedral angle (degrees)", fontsize=7)
    axes.tick_params(labelsize=6)
    axes.set_yticks([])
    figure.tight_layout(pad=0.3)
    figure.canvas.draw()
    rgba = np.asarray(figure.canvas.buffer_rgba())[::-1].copy()  # VTK images start at the bottom row
    height, width = rgba.shape[:2]
    image = vtkImageData()
    image.SetDimensions(width, height, 1)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(rgba.reshape(-1, 4), deep=True))
    mapper = vtkImageMapper()
    mapper.SetInputData(image)
    mapper.SetColorWindow(255.0)
    mapper.SetColorLevel(127.5)
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    actor.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    right = 0.99 - width / max(float(viewport[0]), 1.0)
    actor.GetPositionCoordinate().SetValue(0.01 if corner == "left" else max(right, 0.5), 0.01)
    actor.histogram_size = (width, height)
    return actor


def _scalar_bar():
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    bar = vtkScalarBarActor()
    bar.SetLookupTable(angle_lookup_table())
    bar.SetTitle("min dihedral (degrees)")
    bar.SetNumberOfLabels(4)
    bar.SetWidth(0.08)
    bar.SetHeight(0.45)
    bar.SetPosition(0.9, 0.5)
    return bar


def _status(result) -> str:
    q, p = result.quality, result.parameters
    parts = [f"{q['tetrahedra']:,} tetrahedra", f"{q['points']:,} points",
             f"dihedral {q.get('min_dihedral_deg', float('nan')):.1f}-{q.get('max_dihedral_deg', float('nan')):.1f}"
             " degrees"]
    if "h_mm" in p:
        parts.append(f"h {p['h_mm']:g} mm")
    if result.seconds.get("total"):
        parts.append(f"built in {result.seconds['total']:.2f} s")
    return ", ".join(parts)


class TetMeshContent(ViewContent):
    """The tetrahedra of one method, clipped, coloured by their smallest dihedral angle, with the histogram."""

    result = None
    clipped: ClippedTets | None = None

    def _method(self) -> str:
        return self.mode.method

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None):
        return tetrahedra_for(inputs.item, self._method(), inputs.iso, self.options, progress)

    def install(self, renderer, inputs: ViewInputs, prepared) -> None:
        self.result = prepared
        grid = prepared.unstructured_grid()
        self.clipped = ClippedTets(grid, clip_plane(self.options, grid.GetBounds()))
        self.stats = {k: v for k, v in prepared.quality.items() if k != "histogram"}
        self.stats["seconds"] = dict(prepared.seconds)
        self.histograms = [histogram_actor(prepared, self.mode.label, viewport=renderer.GetSize())]
        self._replace_props(renderer, [self.clipped.actor, _scalar_bar(), *self.histograms])

    def set_clip_plane(self, origin, normal) -> None:
        """Move the clip plane now (the window's widget while it is dragged)."""
        for clipped in self._clipped():
            clipped.set_plane((np.asarray(origin, float), np.asarray(normal, float) / np.linalg.norm(normal)))

    def _clipped(self) -> list[ClippedTets]:
        return [self.clipped] if self.clipped is not None else []

    def bounds(self):
        """Bounds (LPS mm) of the mesh on show, for placing the plane widget."""
        return self.result.unstructured_grid().GetBounds() if self.result is not None else None

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        if change == "iso":
            return REBUILD
        return REDRAW if change == "background" else IGNORE

    def status(self) -> str:
        return _status(self.result) if self.result is not None else ""


class TetComparisonContent(TetMeshContent):
    """Ours (``mode.test``) and a reference (``mode.reference``) side by side, each with its histogram."""

    reference_clipped: ClippedTets | None = None

    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None):
        ours = tetrahedra_for(inputs.item, self.mode.test.method, inputs.iso, self.options,
                              scaled(progress, 0.0, 0.6))
        theirs = tetrahedra_for(inputs.item, self.mode.reference.method, inputs.iso, {},
                                scaled(progress, 0.6, 1.0))
        return ours, theirs

    def install(self, renderer, inputs: ViewInputs, prepared) -> None:
        ours, theirs = prepared
        self.result, self.reference = ours, theirs
        grid = ours.unstructured_grid()
        bounds = np.asarray(grid.GetBounds())
        plane = clip_plane(self.options, bounds)
        # Both meshes at half size about the centre, ours on the patient's right (the left of an anterior view).
        # placed about the item's centre (where the default camera looks), a little above it (the histograms are
        # at the bottom of the view)
        centre = 0.5 * (bounds[0::2] + bounds[1::2])
        item = np.asarray(inputs.item.bounds, dtype=np.float64)
        target = 0.5 * (item[0::2] + item[1::2]) + np.array([0.0, 0.0, 0.12 * (item[5] - item[4])]) - centre
        shift = np.array([0.26 * (bounds[1] - bounds[0]), 0.0, 0.0])
        self.clipped = ClippedTets(grid, plane, offset=target - shift, scale=0.48, centre=centre)
        self.reference_clipped = ClippedTets(theirs.unstructured_grid(), plane, offset=target + shift, scale=0.48,
                                             centre=centre)
        size = renderer.GetSize()
        self.histograms = [histogram_actor(ours, self.mode.test.label, "left", size),
                           histogram_actor(theirs, self.mode.reference.label, "right", size)]
        self.stats = {k: v for k, v in ours.quality.items() if k != "histogram"}
        self.stats["reference"] = {k: v for k, v in theirs.quality.items() if k != "histogram"}
        self._replace_props(renderer, [self.clipped.actor, self.reference_clipped.actor, _scalar_bar(),
                                       *self.histograms])

    def _clipped(self) -> list[ClippedTets]:
        return [c for c in (self.clipped, self.reference_clipped) if c is not None]

    def status(self) -> str:
        if self.result is None:
            return ""
        return f"{self.mode.test.label}: {_status(self.result)} | {self.mode.reference.label}: {_status(self.reference)}"


TETS = dict(group="Tetrahedral meshes", input="volume", output="tetmesh")

register_mode(TetMode(
    "stuffing", "Isosurface stuffing", "Tetrahedra of guaranteed quality (dihedral angles in [10.7, 164.8] degrees) "
    "filling the isosurface, by isosurface stuffing on a BCC lattice (source 002; Labelle & Shewchuk 2007)",
    origin="ours", **TETS, options=STUFFING_OPTIONS + CLIP_OPTIONS, capabilities=CLIPS, method="stuffing",
))
register_mode(TetMode(
    "vtk-delaunay", "Delaunay tetrahedra", "VTK's vtkDelaunay3D on the isosurface's points, the tetrahedra whose "
    "centroid is outside the isosurface removed", origin="VTK", **TETS, options=CLIP_OPTIONS, capabilities=CLIPS,
    method="vtk-delaunay",
))
register_mode(TetMode(
    "vtk-clip-tets", "Clipped voxels (tetrahedra)", "VTK's vtkClipVolume at the isovalue, every voxel inside or cut "
    "split into tetrahedra", origin="VTK", **TETS, options=CLIP_OPTIONS, capabilities=CLIPS, method="vtk-clip-tets",
))
for _reference in ("vtk-clip-tets", "vtk-delaunay"):
    register_mode(TetComparisonMode(
        f"stuffing-vs-{_reference}", f"Stuffing against {get_mode(_reference).label.lower()}",
        f"Our isosurface stuffing beside {get_mode(_reference).description.split(',')[0]}, both clipped and coloured "
        "by their smallest dihedral angle, with both angle histograms", origin="ours", **TETS,
        options=STUFFING_OPTIONS + CLIP_OPTIONS, capabilities=CLIPS, method="stuffing", test=get_mode("stuffing"),
        reference=get_mode(_reference),
    ))
register_mode(TetMode(
    "tetmesh", "Tetrahedral mesh", "A tetrahedral mesh of the scene, clipped and coloured by its smallest dihedral "
    "angle (patient coordinates, mm)", origin="ours", group="Tetrahedral meshes", input="tetmesh", output="tetmesh",
    options=CLIP_OPTIONS, capabilities=Capabilities(clip_plane=True), method="item",
))
