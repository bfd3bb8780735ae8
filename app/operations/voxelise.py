"""The "voxelise" operation: a surface mesh of the scene to a mask on a grid (source 002, section 2.2).

The grid is the ``like`` volume's (its exact dimensions, spacing, origin and direction) when one is given, else an
axis-aligned grid around the mesh: ``grid`` cubic voxels along its longest side, or the given ``spacing``, with
``padding`` voxels of margin. The mask is made by :class:`algorithms.fields.voxelise.VoxeliseFilter` (the VTK
filter every pipeline uses), with progress and Cancel forwarded. The mesh is checked before anything is allocated
(:func:`check_mesh`): what is wrong with it and what to do come back as one line (a ValueError), and what only
deserves a note goes into the result's ``warnings``. The report (:attr:`OperationResult.report`, also the mask
item's ``metadata["voxelise"]``) is what ``voxelscope voxelise --json`` prints.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from algorithms.common.grid import Grid

from ..options import Option
from . import register_operation
from .base import Input, Operation, OperationResult

#: Voxels along the mesh's longest side when neither a ``like`` volume nor a spacing is given.
DEFAULT_GRID = 256


def parse_spacing(text) -> tuple[float, float, float] | None:
    """``"0.5"`` or ``"0.5 0.5 2"`` (commas allowed) as three positive mm; None for None or empty text."""
    if text is None or (isinstance(text, str) and not text.strip()):
        return None
    parts = text.replace(",", " ").split() if isinstance(text, str) else list(text)
    try:
        values = [float(v) for v in parts]
    except (TypeError, ValueError):
        raise ValueError(f"--spacing takes one or three numbers in mm (x, y, z), got {text!r}") from None
    if len(values) == 1:
        values *= 3
    if len(values) != 3 or not all(np.isfinite(values)) or min(values) <= 0:
        raise ValueError(f"--spacing takes one or three positive numbers in mm (x, y, z), got {text!r}")
    return tuple(values)


def checked_mesh(mesh_item, rule: str, purpose: str) -> tuple[np.ndarray, np.ndarray, dict, dict, list[str]]:
    """A mesh item's points (float64, LPS mm) and triangles, its description (:func:`app.io.meshes.describe_mesh`),
    its topology facts and warnings (:func:`check_mesh`); a one-line ValueError for what no field can be made of
    (``purpose`` ends the sentence: "so there is nothing to voxelise")."""
    from algorithms.common.vtk_bridge import polydata_arrays

    from ..io.meshes import Mesh, describe_mesh

    try:
        points, triangles = polydata_arrays(mesh_item.polydata)
    except ValueError:
        raise ValueError(f"{mesh_item.name} holds polygons other than triangles; triangulate it first") from None
    points = np.asarray(points, dtype=np.float64)
    if len(triangles) == 0:
        raise ValueError(f"{mesh_item.name} has no triangles, {purpose}; open a surface mesh")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{mesh_item.name} has points with NaN or infinite coordinates; repair or re-export it")
    info = describe_mesh(Mesh(mesh_item.polydata, mesh_item.metadata.get("source_path", mesh_item.name),
                              mesh_item.metadata.get("source_format", "mesh"),
                              list(mesh_item.metadata.get("warnings", []))))
    facts, warnings = check_mesh(mesh_item.name, points, triangles, rule, info)
    return points, triangles, info, facts, warnings


def check_mesh(name: str, points: np.ndarray, triangles: np.ndarray, rule: str, info: dict) -> tuple[dict, list[str]]:
    """Topology facts of the mesh and the warnings it deserves; ValueError (one line: what is wrong, what to do)
    when ``rule`` cannot give a sensible mask for it. ``info`` is the mesh's :func:`app.io.meshes.describe_mesh`."""
    from algorithms.compare.topology import edge_manifoldness
    from algorithms.fields.winding import boundary_caps

    if len(triangles) == 0:
        raise ValueError(f"{name} has no triangles, so there is nothing to voxelise; open a surface mesh")
    if not np.all(np.isfinite(points)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(points), axis=1)))
        raise ValueError(f"{name} has {bad} point(s) with NaN or infinite coordinates; repair or re-export the mesh")
    edges = edge_manifoldness(points, triangles)
    closed = edges.odd_edges == 0
    holes = 0 if closed else boundary_caps(points, triangles).count
    facts = {"boundary_edges": edges.boundary_edges, "non_manifold_edges": edges.nonmanifold_edges,
             "odd_edges": edges.odd_edges, "inconsistent_edges": edges.inconsistent_edges, "holes": holes,
             "components": info["components"], "orientation": info["orientation"]}
    warnings: list[str] = []
    if len(triangles) < 4 or (closed and not info.get("volume_mm3") and info["orientation"] == "undefined"):
        raise ValueError(f"{name} encloses no volume ({len(triangles)} triangle(s), "
                         f"{'closed' if closed else f'{edges.boundary_edges} boundary edges'}); voxelise a closed "
                         "surface around a solid")
    if not closed:
        what = (f"{name} is open: {edges.boundary_edges:,} boundary edges around {holes} hole(s)"
                + (f", {edges.odd_edges - edges.boundary_edges:,} edges shared by 3 or more triangles"
                   if edges.odd_edges > edges.boundary_edges else ""))
        if rule == "parity":
            raise ValueError(f"{what}, so inside and outside are undefined by parity; use --inside winding (the "
                             "generalised winding number closes small holes), or close the holes first")
        warnings.append(f"{what}; the winding-number rule closes them")
    if edges.nonmanifold_edges and closed:
        warnings.append(f"{name} has {edges.nonmanifold_edges:,} non-manifold edges (surfaces touching along an "
                        "edge); it is still closed, so the mask is well defined")
    if edges.inconsistent_edges:
        if rule == "winding":
            raise ValueError(f"{name} is not consistently oriented (its winding flips across "
                             f"{edges.inconsistent_edges:,} edges), so its winding number is meaningless; "
                             + ("use --inside parity (the mesh is closed)" if closed else
                                "re-orient it in a mesh editor first"))
        warnings.append(f"{name} is not consistently oriented ({edges.inconsistent_edges:,} edges where the winding "
                        "flips); parity does not depend on orientation, so the mask is right")
    elif info["orientation"] == "inward":
        if rule == "winding":
            raise ValueError(f"{name} faces inward (its enclosed volume is negative), so its winding number is -1 "
                             "inside and the winding rule finds no solid; use --inside parity, or flip its triangles")
        warnings.append(f"{name} faces inward (negative enclosed volume); parity does not depend on orientation, "
                        "so the mask is right, but flip the mesh before using it elsewhere")
    return facts, warnings


def _mesh_volume(points, triangles, facts) -> tuple[float | None, str]:
    """Enclosed volume (mm^3) and how it was measured: the mesh itself when closed, else closed by fans."""
    from algorithms.compare.measures import enclosed_volume
    from algorithms.fields.winding import boundary_caps

    if facts["odd_edges"] == 0:
        return abs(float(enclosed_volume(points, triangles))), "closed mesh"
    caps = boundary_caps(points, triangles)
    closed = np.concatenate([triangles, caps.triangles])
    return abs(float(enclosed_volume(caps.points, closed))), f"mesh closed by fans over its {caps.count} hole(s)"


def output_grid(mesh_bounds, like=None, *, grid: int | None = None, spacing=None, padding: int = 2):
    """The grid a mask is made on (see the module notes)."""
    spacing = parse_spacing(spacing)
    if like is not None:
        if grid is not None or spacing is not None:
            raise ValueError("give either a volume to copy the grid from (--like) or --grid/--spacing, not both")
        return like.volume.grid
    if grid is not None and spacing is not None:
        raise ValueError("give either --grid N (voxels along the longest side) or --spacing, not both")
    if spacing is not None:
        return Grid.around(mesh_bounds, spacing=spacing, padding=padding)
    return Grid.around(mesh_bounds, voxels=DEFAULT_GRID if grid is None else grid, padding=padding)


def _check_grid(name: str, grid, points: np.ndarray, like_name: str | None) -> list[str]:
    """Refuse grids too large for memory or missing the mesh entirely; warn when the mesh leaves the grid."""
    from ..io.safety import gib, memory_available

    needed = grid.size * 2  # the mask, and the written copy
    if needed > memory_available():
        raise ValueError(f"a grid of {' x '.join(map(str, grid.dimensions))} voxels needs {gib(needed)} and only "
                         f"{gib(memory_available())} is free; use a smaller --grid or a coarser --spacing")
    index = grid.world_to_index(points)
    low, high = index.min(axis=0), index.max(axis=0)
    size = np.asarray(grid.dimensions) - 1
    if np.any(high < 0) or np.any(low > size):
        where = like_name or "the grid"
        raise ValueError(f"{name} lies outside {where} (mesh bounds {_bounds_text(points)} mm, grid "
                         f"{_bounds_text(grid.index_to_world(np.array([[0, 0, 0], size])))} mm); check that both are "
                         "in the same patient coordinates (LPS mm)")
    if np.any(low < 0) or np.any(high > size):
        return [f"part of {name} lies outside {like_name or 'the grid'}; the mask is cut at the grid's edge"]
    return []


def _bounds_text(points) -> str:
    low, high = np.min(points, axis=0), np.max(points, axis=0)
    return "x {:.1f}..{:.1f}, y {:.1f}..{:.1f}, z {:.1f}..{:.1f}".format(*np.ravel(np.column_stack([low, high])))


class Voxelise(Operation):
    """A mesh to a mask: 1 where a voxel centre is inside (parity or winding number)."""

    def check_options(self, options: Mapping[str, Any]) -> None:
        parse_spacing(options.get("spacing"))
        if options.get("grid") is not None and options.get("spacing") not in (None, ""):
            raise ValueError("give either --grid N (voxels along the longest side) or --spacing, not both")

    def run(self, items: Mapping[str, Any], options: Mapping[str, Any], *, progress=None) -> OperationResult:
        from algorithms.common.vtk_bridge import run_algorithm
        from algorithms.fields.voxelise import VoxeliseFilter, warm_up
        from vtkmodules.util.numpy_support import vtk_to_numpy

        from ..scene import FieldItem
        from ..volume import Volume

        self.check_inputs(items)
        mesh_item, like = items["mesh"], items.get("like")
        rule = options["inside"]
        points, triangles, mesh_info, facts, warnings = checked_mesh(mesh_item, rule, "so there is nothing to voxelise")
        grid = output_grid(mesh_item.bounds, like, grid=options["grid"], spacing=options["spacing"],
                           padding=options["padding"])
        warnings += _check_grid(mesh_item.name, grid, points, like.name if like is not None else None)
        loading = warm_up()  # numba's kernels, loaded once per process: not part of the voxelisation's time
        # through the VTK filter, as every pipeline does (progress and Cancel forwarded; its report kept)
        voxeliser = VoxeliseFilter()
        voxeliser.SetInputDataObject(0, mesh_item.polydata)
        voxeliser.SetGrid(grid)
        voxeliser.SetInside(rule)
        image = run_algorithm(voxeliser, progress)
        run = voxeliser.GetReport()
        mask = np.array(vtk_to_numpy(image.GetPointData().GetScalars()).reshape(grid.shape), dtype=np.uint8)
        inside = int(np.count_nonzero(mask))
        if inside == 0:
            raise ValueError(f"no voxel centre of the grid lies inside {mesh_item.name} (voxels of "
                             f"{' x '.join(f'{s:.3g}' for s in grid.spacing)} mm); use a finer --grid or --spacing")
        mesh_volume, measured = _mesh_volume(points, triangles, facts)
        report = {
            **grid.describe(),
            "inside_voxels": inside,
            "volume_mm3": inside * grid.voxel_volume,
            "mesh_volume_mm3": mesh_volume,
            "mesh_volume_measured_on": measured,
            "rule": rule,
            "seconds": run.seconds,
            "kernel_load_seconds": loading,
            "crossings": run.crossings,
            "holes_closed": run.caps,
            "voxels_refined_near_holes": run.tree_voxels,
            "grid_from": f"like {like.name}" if like is not None else (
                f"spacing {options['spacing']}" if options["spacing"] else
                f"{options['grid'] or DEFAULT_GRID} voxels along the longest side, padding {options['padding']}"),
            "mesh": mesh_info,
            "warnings": warnings,
        }
        volume = Volume.on_grid(mask, grid, modality="mask", units="",
                                metadata={"source_format": "voxelised mesh", "source_path": mesh_item.name,
                                          "warnings": warnings})
        item = FieldItem(f"{mesh_item.name} mask", volume=volume, role="mask",
                         metadata={"source": mesh_item.name, "voxelise": report, "warnings": warnings})
        return OperationResult(item, report)


#: The optional input every field operation takes its grid from.
LIKE_INPUT = Input("like", ("volume", "field"), "use this volume's grid (dimensions, spacing, origin, direction)",
                   optional=True)
#: How a field operation tells the inside of a mesh from its outside.
INSIDE_OPTION = Option("inside", "str", "parity", "inside rule: parity of crossings (closed meshes) or winding number "
                       "(meshes with holes or self-intersections)", choices=("parity", "winding"))


def grid_options(padding: int) -> tuple[Option, ...]:
    """The options of a field operation's grid around its meshes (unless a ``like`` volume gives it): voxels along
    the longest side or a spacing, and a margin of ``padding`` voxels by default."""
    return (
        Option("grid", "int", None, f"voxels along the meshes' longest side, cubic voxels (default {DEFAULT_GRID} "
               "when no 'like' volume and no spacing is given)", minimum=2, maximum=4096),
        Option("spacing", "str", None, "voxel size in mm: one number (cubic) or three (x y z), instead of grid"),
        Option("padding", "int", padding, "voxels of margin around the meshes' bounding box", minimum=0,
               maximum=1024),
    )


register_operation(Voxelise(
    "voxelise", "Voxelise mesh", "A closed surface mesh as a mask on a grid: 1 where a voxel centre is inside, by "
    "parity of row crossings (closed meshes) or the generalised winding number (meshes with holes)",
    inputs=(Input("mesh", ("mesh",), "the surface mesh"), LIKE_INPUT),
    output="field", group="Fields", options=grid_options(padding=2) + (INSIDE_OPTION,),
))
