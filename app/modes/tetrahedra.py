"""Tetrahedral-mesh modes: a volume's (or field's) isosurface filled with tetrahedra, shown cut open by a plane and
coloured by each tetrahedron's smallest dihedral angle, with the angle histogram in the view.

Ours: ``stuffing`` (isosurface stuffing, Labelle & Shewchuk 2007; source 002, chapter 4). VTK's: ``vtk-delaunay``
(``vtkDelaunay3D`` on the isosurface's points, the tetrahedra outside removed) and ``vtk-clip-tets``
(``vtkClipVolume``, tetrahedra only). ``stuffing-vs-vtk-clip-tets`` and ``stuffing-vs-vtk-delaunay`` show ours
beside VTK's with both histograms; ``tetmesh`` shows a tetrahedral mesh of the scene.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from ..pipeline.tetrahedra import TetComparisonContent, TetMeshContent, clip_plane
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

    def create_content(self, options: Mapping[str, Any]) -> TetMeshContent:
        return TetMeshContent(self, options)

    def check_options(self, options: Mapping[str, Any]) -> None:
        clip_plane(options, (0, 0, 0, 0, 0, 0))  # refuses malformed planes before any work


@dataclass(frozen=True)
class TetComparisonMode(TetMode):
    test: str = ""
    reference: str = ""

    def create_content(self, options: Mapping[str, Any]) -> TetComparisonContent:
        return TetComparisonContent(self, options)


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
        options=STUFFING_OPTIONS + CLIP_OPTIONS, capabilities=CLIPS, method="stuffing", test="stuffing",
        reference=_reference,
    ))
register_mode(TetMode(
    "tetmesh", "Tetrahedral mesh", "A tetrahedral mesh of the scene, clipped and coloured by its smallest dihedral "
    "angle (patient coordinates, mm)", origin="ours", group="Tetrahedral meshes", input="tetmesh", output="tetmesh",
    options=CLIP_OPTIONS, capabilities=Capabilities(clip_plane=True), method="item",
))
