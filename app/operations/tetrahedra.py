"""Operations that make tetrahedral meshes: a volume or field -> a :class:`~app.scene.TetMeshItem` (patient
coordinates, LPS mm) by isosurface stuffing (ours) or by VTK's tetrahedralisations.

:func:`tetrahedralise` is the one function behind the operation, the ``tetmesh`` command, the tetrahedral render
modes and the benchmark: it chooses the isovalue and lattice spacing, runs the method, moves the mesh into the
patient and measures its quality.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from algorithms.common.progress import scaled

from ..options import Option
from . import register_operation
from .base import Input, Operation, OperationResult

#: The tetrahedralisations by name: ours and VTK's two.
METHODS = ("stuffing", "vtk-delaunay", "vtk-clip-tets")
#: Cell array of the smallest dihedral angle of each tetrahedron (degrees).
MIN_ANGLE_ARRAY = "min_dihedral_deg"


@dataclass
class TetResult:
    """A tetrahedral mesh in patient coordinates and what is known about it.

    ``mesh``: :class:`~algorithms.common.mesh.TetMesh` (LPS mm); ``boundary``: its boundary triangles (indices into
    ``mesh.points``, outward) or None; ``min_angles``: smallest dihedral angle per tetrahedron (degrees);
    ``quality``: :func:`algorithms.compare.tet_quality.quality_report`; ``seconds``: the method's breakdown;
    ``parameters``: method, iso, h, alpha, inside.
    """

    mesh: Any
    boundary: np.ndarray | None
    min_angles: np.ndarray
    quality: dict[str, Any]
    seconds: dict[str, float] = field(default_factory=dict)
    parameters: dict[str, Any] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)

    def unstructured_grid(self):
        """The mesh as a ``vtkUnstructuredGrid`` with the cell array ``min_dihedral_deg``."""
        return self.mesh.to_unstructured_grid(cell_data={MIN_ANGLE_ARRAY: self.min_angles.astype(np.float32)})


def default_h(volume) -> float:
    """Twice the smallest voxel spacing (mm): about 1.6 M tetrahedra for the sample CT's skull."""
    return round(2.0 * float(min(volume.spacing)), 3)


def _inside_and_iso(source, iso):
    """Which side is inside, and the isovalue: distance fields are negative inside (0 mm), masks 0.5."""
    from ..volume import default_iso

    volume = source.volume if hasattr(source, "volume") else source
    role = getattr(source, "role", None)
    if role == "distance":
        return volume, "below", 0.0 if iso is None else float(iso)
    if iso is None:
        iso = source.iso if role is not None else default_iso(volume)
    return volume, "above", float(iso)


def _to_world(mesh, volume):
    """The mesh, computed in the volume frame (index times spacing, mm), in patient coordinates (LPS mm);
    tetrahedra reordered if the volume's axes are left-handed."""
    from algorithms.common.mesh import TetMesh

    matrix = volume.local_to_world
    points = mesh.points @ matrix[:3, :3].T + matrix[:3, 3]
    tets = mesh.tetrahedra
    if np.linalg.det(matrix[:3, :3]) < 0:
        tets = tets[:, [1, 0, 2, 3]]
    return TetMesh(points, tets)


def tetrahedralise(source, *, method: str = "stuffing", iso: float | None = None, h: float | None = None,
                   alpha: str = "10.7", conformity: bool = False,
                   progress=None) -> TetResult:
    """Tetrahedra filling the isosurface of a volume item, field item or :class:`~app.volume.Volume`.

    ``method`` is one of :data:`METHODS`; ``h`` (mm, default :func:`default_h`) and ``alpha`` apply to stuffing. ``conformity`` adds the face and boundary checks to the quality report (slower on large meshes).
    """
    from algorithms.compare.tet_quality import min_max_dihedral, quality_report

    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    volume, inside, iso = _inside_and_iso(source, iso)
    parameters: dict[str, Any] = {"method": method, "iso": iso, "iso_units": volume.units_label, "inside": inside}
    start = time.perf_counter()
    boundary = None
    stats: dict[str, Any] = {}
    if method == "stuffing":
        from algorithms.meshing.isosurface_stuffing import ANGLE_BOUNDS, isosurface_stuffing, resolve_alphas

        name, pair = resolve_alphas(alpha)
        h = default_h(volume) if h is None else float(h)
        parameters.update({"h_mm": h, "alpha": name, "alpha_long": pair[0], "alpha_short": pair[1]})
        result = isosurface_stuffing(volume.array, iso, h=h, spacing=volume.spacing, origin=(0.0, 0.0, 0.0),
                                     alpha=name, inside=inside, progress=scaled(progress, 0.0, 0.8))
        local, boundary, seconds, stats = result.mesh, result.boundary, dict(result.seconds), dict(result.stats)
        bounds = ANGLE_BOUNDS[name]
    else:
        from algorithms.references.vtk_tetrahedra import vtk_clip_tetrahedra, vtk_delaunay_tetrahedra

        run = vtk_delaunay_tetrahedra if method == "vtk-delaunay" else vtk_clip_tetrahedra
        result = run(volume.array, iso, spacing=volume.spacing, origin=(0.0, 0.0, 0.0), inside=inside,
                     progress=scaled(progress, 0.0, 0.8))
        local, seconds, stats = result.mesh, dict(result.seconds), dict(result.stats)
        bounds = None
    if local.n_tetrahedra == 0:
        lo, hi = volume.value_range
        raise ValueError(f"no tetrahedra at {iso:g} {volume.units_label} (values {lo:g} to {hi:g}); choose another "
                         "isovalue")
    tick = time.perf_counter()
    mesh = _to_world(local, volume)
    seconds["world"] = time.perf_counter() - tick
    seconds.setdefault("total", time.perf_counter() - start)
    seconds["total"] = max(seconds["total"], time.perf_counter() - start)
    if progress is not None:
        progress(0.85)
    smallest, _ = min_max_dihedral(mesh.points, mesh.tetrahedra)
    quality = quality_report(mesh.points, mesh.tetrahedra, bounds=bounds, with_conformity=conformity)
    if progress is not None:
        progress(1.0)
    return TetResult(mesh, boundary, smallest, quality, seconds, parameters, stats)


class MakeTetrahedra(Operation):
    """A volume's (or field's) isosurface filled with tetrahedra, as a tetrahedral mesh item in LPS mm."""

    def run(self, items: Mapping[str, Any], options: Mapping[str, Any], *, progress=None) -> OperationResult:
        from ..scene import TetMeshItem

        source = items["volume"]
        result = tetrahedralise(source, method=options["method"], iso=options["iso"], h=options["h"],
                                alpha=options["alpha"], progress=progress)
        p = result.parameters
        label = {"stuffing": "stuffed", "vtk-delaunay": "Delaunay", "vtk-clip-tets": "clipped"}[p["method"]]
        name = f"{source.name} tetrahedra ({label}) {p['iso']:g} {p['iso_units']}".replace("  ", " ")
        quality = {k: v for k, v in result.quality.items() if k != "histogram"}
        item = TetMeshItem(name, grid=result.unstructured_grid(),
                           metadata={"source": source.name, **p, "quality": quality, "seconds": result.seconds})
        return OperationResult(item, {**p, **quality, "seconds": result.seconds})


register_operation(MakeTetrahedra(
    "tetrahedra", "Fill with tetrahedra", "The isosurface of a volume or field filled with tetrahedra (LPS mm): "
    "isosurface stuffing with guaranteed dihedral angles, or VTK's Delaunay or clip tetrahedralisation",
    inputs=(Input("volume", ("volume", "field"), "the volume or field"),), output="tetmesh",
    group="Tetrahedral meshes",
    options=(
        Option("method", "str", "stuffing", "tetrahedralisation: stuffing (ours), vtk-delaunay or vtk-clip-tets",
               choices=METHODS),
        Option("iso", "float", None, "isovalue in the volume's units (default: 300 HU for CT, 0 mm for distance "
               "fields, 0.5 for masks, else 35 % into the value range)"),
        Option("h", "float", None, "stuffing: lattice spacing (default twice the smallest voxel spacing)", unit="mm",
               minimum=0.01, maximum=1000.0),
        Option("alpha", "str", "10.7", "stuffing: the paper's parameter pair, by its lower angle bound (10.7: angles "
               "in [10.7, 164.8] degrees; 8.9: in [8.9, 158.8])", choices=("10.7", "8.9")),
    ),
))
