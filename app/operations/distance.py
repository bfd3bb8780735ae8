"""The "distance" and "csg" operations: a mesh's signed distance field on a grid, and union / intersection /
difference of meshes, fields and volumes' isosurfaces as a distance field (source 002, chapter 3).

"distance": mesh (+ optional ``like`` volume for the grid) -> ``FieldItem(role="distance")``, float32 mm, negative
inside; exact within the band (``band``: mm, or per cent of the mesh's height with ``%``), clamped to +-band or
propagated outside it; the sign from voxelisation (``inside`` rule). The mesh is checked first
(:func:`app.operations.voxelise.check_mesh`: one-line errors for meshes without an inside).

Reports: ``seconds`` is the total (the window shows it), ``timing`` the breakdown (the commands print it as
``seconds``).

"csg": inputs ``a``, ``b`` (and optionally ``c``, ``d``): meshes, distance fields, masks or volumes; every input
becomes a field on one grid (the ``like`` volume's, else the first gridded input's, else a grid around all meshes),
meshes through "distance", fields resampled when their grid differs, volumes through their isosurface (``iso``), then
:func:`algorithms.fields.csg.combine`. The report gives ``seconds`` per step; the result meshes with marching cubes
(:func:`mesh_result`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from algorithms.common.grid import Grid
from algorithms.common.progress import ProgressCallback, report, scaled

from ..options import Option
from . import register_operation
from .base import Input, Operation, OperationResult
from .voxelise import (
    DEFAULT_GRID,
    INSIDE_OPTION,
    LIKE_INPUT,
    _check_grid,
    checked_mesh,
    grid_options,
    output_grid,
    parse_spacing,
)

#: Bytes per voxel while a distance field is made: values, nearest triangle, mask, and the written copy.
BYTES_PER_VOXEL = 16
CSG_OPERATIONS = ("union", "intersection", "difference")


def parse_band(text, points, grid) -> float:
    """``"2.5"`` (mm) or ``"5%"`` (of the mesh's height along the grid's k axis) as mm."""
    from algorithms.fields.distance import band_from_percent

    raw = str(text).strip()
    try:
        if raw.endswith("%"):
            return band_from_percent(points, grid, float(raw[:-1]))
        value = float(raw)
    except ValueError as error:
        if "percent" in str(error) or "extent" in str(error):
            raise
        raise ValueError(f"the band is a width in mm (e.g. 3) or a percentage of the mesh's height (e.g. 5%), got "
                         f"{text!r}") from None
    if not (value > 0 and np.isfinite(value)):
        raise ValueError(f"the band must be a positive width in mm, got {text!r}")
    return value


def _check_memory(grid, what: str) -> None:
    from ..io.safety import gib, memory_available

    needed = grid.size * BYTES_PER_VOXEL
    if needed > memory_available():
        raise ValueError(f"{what} on {' x '.join(map(str, grid.dimensions))} voxels needs about {gib(needed)} and "
                         f"only {gib(memory_available())} is free; use a smaller --grid or a coarser --spacing")


def mesh_distance(mesh_item, grid, *, band: str, outside: str, inside: str, progress=None):
    """A mesh item's signed distance field on ``grid``: ``(DistanceField, report dict)``."""
    from algorithms.fields.distance import signed_distance

    points, triangles, _, facts, warnings = checked_mesh(mesh_item, inside, "so it has no distance field")
    warnings = warnings + _check_grid(mesh_item.name, grid, points, None)
    _check_memory(grid, f"the distance field of {mesh_item.name}")
    band_mm = parse_band(band, points, grid)
    field = signed_distance(points, triangles, grid, band_mm=band_mm, outside=outside, inside=inside,
                            progress=progress)
    if field.stats["inside_voxels"] == 0:
        warnings.append(f"no voxel centre lies inside {mesh_item.name}; the field is positive everywhere")
    low, high = field.value_range
    report = {**grid.describe(), "band_mm": band_mm, "outside": outside, "inside_rule": inside,
              "seconds": field.seconds["total"], "timing": field.seconds, "value_range_mm": [low, high],
              "triangles": int(len(triangles)),
              "inside_voxels": field.stats["inside_voxels"], "stats": field.stats, "mesh": facts,
              "warnings": warnings}
    return field, report


def distance_item(name: str, values, grid, metadata: dict):
    from ..scene import FieldItem
    from ..volume import Volume

    volume = Volume.on_grid(values, grid, modality="distance", units="mm",
                            metadata={"source_format": "distance field", "source_path": name})
    return FieldItem(name, volume=volume, role="distance", metadata=metadata)


class Distance(Operation):
    """A mesh to its signed distance field (mm, negative inside)."""

    def check_options(self, options: Mapping[str, Any]) -> None:
        parse_spacing(options.get("spacing"))

    def run(self, items: Mapping[str, Any], options: Mapping[str, Any], *, progress=None) -> OperationResult:
        self.check_inputs(items)
        mesh_item, like = items["mesh"], items.get("like")
        grid = output_grid(mesh_item.bounds, like, grid=options["grid"], spacing=options["spacing"],
                           padding=options["padding"])
        field, report = mesh_distance(mesh_item, grid, band=options["band"], outside=options["outside"],
                                      inside=options["inside"], progress=progress)
        item = distance_item(f"{mesh_item.name} distance", field.values, grid,
                             {"source": mesh_item.name, "distance": report, "warnings": report["warnings"]})
        return OperationResult(item, report)


def _field_values(item, grid, options, progress) -> tuple[np.ndarray, dict]:
    """An input of "csg" as a distance-like field on ``grid`` (mm, negative inside) and what was done to it."""
    from algorithms.fields.csg import isosurface_field

    from ..volume import default_iso
    from ..volume import Volume

    if item.kind == "mesh":
        field, report = mesh_distance(item, grid, band=options["band"], outside=options["outside"],
                                      inside=options["inside"], progress=progress)
        return field.values, {"from": "mesh", **{k: report[k] for k in ("band_mm", "seconds", "timing", "warnings")}}
    volume = item.volume
    role = getattr(item, "role", None)
    start = time.perf_counter()
    if role == "distance":
        values, how = np.asarray(volume.array, np.float32), "distance field"
    elif role == "mask":
        values = isosurface_field(volume.array.astype(np.float32), 0.5, spacing=volume.spacing)
        how = "mask (its 0.5 level, scaled to mm)"
    else:
        iso = options["iso"] if options["iso"] is not None else default_iso(volume)
        values = isosurface_field(volume.array, float(iso), spacing=volume.spacing)
        how = f"isosurface at {float(iso):g} {volume.units_label} (scaled to mm by its gradient)"
    note = {"from": how}
    if not volume.grid.same_as(grid):
        source = Volume.on_grid(values, volume.grid)
        values = source.resampled(grid, order=1, fill=float(values.max())).array
        note["resampled"] = True
    note["seconds"] = time.perf_counter() - start
    return values, note


def common_grid(items, like, options):
    """The grid of a CSG (see the module notes)."""
    spacing = parse_spacing(options.get("spacing"))
    if like is not None:
        return like.volume.grid, f"like {like.name}"
    gridded = [item for item in items if item.kind != "mesh"]
    if gridded and options.get("grid") is None and spacing is None:
        return gridded[0].volume.grid, f"the grid of {gridded[0].name}"
    bounds = np.array([item.bounds for item in items], dtype=np.float64)
    around = (bounds[:, 0].min(), bounds[:, 1].max(), bounds[:, 2].min(), bounds[:, 3].max(), bounds[:, 4].min(),
              bounds[:, 5].max())
    if spacing is not None:
        return Grid.around(around, spacing=spacing, padding=options["padding"]), f"spacing {options['spacing']}"
    n = options.get("grid") or DEFAULT_GRID
    return Grid.around(around, voxels=n, padding=options["padding"]), f"{n} voxels along the longest side"


class Csg(Operation):
    """Union, intersection or difference of two to four meshes, fields or volumes, as a distance field."""

    def check_options(self, options: Mapping[str, Any]) -> None:
        parse_spacing(options.get("spacing"))

    def run(self, items: Mapping[str, Any], options: Mapping[str, Any], *, progress=None) -> OperationResult:
        from algorithms.fields.csg import combine

        self.check_inputs(items)
        inputs = [items[name] for name in ("a", "b", "c", "d") if items.get(name) is not None]
        like = items.get("like")
        grid, grid_from = common_grid(inputs, like, options)
        _check_memory(grid, "the CSG")
        values, notes = [], []
        for n, item in enumerate(inputs):
            part = scaled(progress, n / (len(inputs) + 1), (n + 1) / (len(inputs) + 1))
            field, note = _field_values(item, grid, options, part)
            values.append(field)
            notes.append({"name": item.name, **note})
        start = time.perf_counter()
        result = combine(values, options["operation"], blend_mm=options["blend"])
        boolean_seconds = time.perf_counter() - start
        if progress is not None:
            progress(1.0)
        symbol = {"union": " + ", "intersection": " & ", "difference": " - "}[options["operation"]]
        name = symbol.join(item.name for item in inputs)
        low, high = float(result.min()), float(result.max())
        warnings = [w for note in notes for w in note.get("warnings", [])]
        if not low < 0:
            raise ValueError(f"the {options['operation']} of {', '.join(i.name for i in inputs)} is empty: no voxel "
                             "centre of the grid is inside it; check the inputs' positions or use a finer grid")
        report = {**grid.describe(), "operation": options["operation"], "blend_mm": options["blend"],
                  "grid_from": grid_from, "inputs": notes, "value_range_mm": [low, high],
                  "seconds": sum(note.get("seconds", 0.0) for note in notes) + boolean_seconds,
                  "timing": {"inputs": [note.get("seconds") for note in notes], "boolean": boolean_seconds},
                  "warnings": warnings}
        item = distance_item(name, result, grid, {"source": [i.name for i in inputs], "csg": report,
                                                  "warnings": warnings})
        return OperationResult(item, report)


@dataclass
class CsgMesh:
    """A field's zero set (or offset) as a mesh: ``points`` (n, 3) LPS mm, ``triangles`` (m, 3) counter-clockwise
    seen from outside, and ``seconds``."""

    points: np.ndarray
    triangles: np.ndarray
    seconds: float
    stats: dict = field(default_factory=dict)


def mesh_field(values: np.ndarray, grid, *, offset_mm: float = 0.0,
               progress: ProgressCallback = None) -> CsgMesh:
    """The surface ``f = offset_mm`` of a field (negative inside) by our marching cubes, in LPS mm, facing out.

    Always closed: the field is padded by one voxel of "outside" first, so a solid cut by the grid's border gets a
    cap within one voxel outside the grid instead of an open rim.
    """
    from algorithms.fields.csg import negated_padded
    from algorithms.surfaces.marching_cubes import marching_cubes

    start = time.perf_counter()
    values = np.asarray(values)
    if values.shape != grid.shape:
        raise ValueError(f"a field of shape {values.shape} does not fit a grid of shape {grid.shape}")
    # marching cubes puts inside at value >= level and faces away from it: negate the field (and pad it)
    padded = negated_padded(values, offset_mm)
    mesh = marching_cubes(padded, -float(offset_mm), spacing=grid.spacing,
                          origin=tuple(-np.asarray(grid.spacing)), progress=progress)
    direction = grid.direction_matrix
    points = np.asarray(mesh.points, np.float64) @ direction.T + np.asarray(grid.origin)
    triangles = np.asarray(mesh.triangles, np.int64)
    if np.linalg.det(direction) < 0:
        triangles = triangles[:, [0, 2, 1]]
    report(progress, 1.0)
    return CsgMesh(points, triangles, time.perf_counter() - start, {"triangles": int(len(triangles)),
                                                                     "points": int(len(points))})


def mesh_result(item, *, offset_mm: float = 0.0):
    """The surface ``f = offset_mm`` of a distance field item as a mesh item (LPS mm, facing out) and the seconds."""
    from algorithms.common.vtk_bridge import polydata_from_arrays

    from ..scene import MeshItem

    mesh = mesh_field(item.volume.array, item.volume.grid, offset_mm=offset_mm)
    if len(mesh.triangles) == 0:
        lo, hi = item.volume.value_range
        raise ValueError(f"{item.name}: no surface at {offset_mm:g} mm (the field runs from {lo:g} to {hi:g} mm); "
                         "the result is empty or fills the grid")
    polydata = polydata_from_arrays(mesh.points, mesh.triangles)
    return MeshItem(f"{item.name} surface", polydata=polydata, metadata={"source": item.name}), mesh.seconds


_GRID_OPTIONS = grid_options(padding=4)
_DISTANCE_OPTIONS = (
    Option("band", "str", "10%", "width of the exact band: mm (e.g. 3) or per cent of the mesh's height (e.g. 5%)"),
    Option("outside", "str", "clamp", "outside the band: clamp to +-band, or propagate exact nearest-triangle "
           "distances over the whole grid", choices=("clamp", "propagate")),
    INSIDE_OPTION,
)

register_operation(Distance(
    "distance", "Signed distance field", "A mesh's signed distance field on a grid (mm, negative inside): exact in a "
    "band around the mesh, clamped or propagated outside it",
    inputs=(Input("mesh", ("mesh",), "the surface mesh"), LIKE_INPUT),
    output="field", group="Fields", options=_GRID_OPTIONS + _DISTANCE_OPTIONS,
))

register_operation(Csg(
    "csg", "Combine solids (CSG)", "Union, intersection or difference of meshes, distance fields, masks or volumes' "
    "isosurfaces, as a distance field (mm, negative inside); smooth with a blend radius",
    inputs=(Input("a", ("mesh", "field", "volume"), "the first solid"),
            Input("b", ("mesh", "field", "volume"), "the second solid (subtracted from the first for a difference)"),
            Input("c", ("mesh", "field", "volume"), "a third solid", optional=True),
            Input("d", ("mesh", "field", "volume"), "a fourth solid", optional=True),
            LIKE_INPUT),
    output="field", group="Fields",
    options=(Option("operation", "str", "difference", "union, intersection, or difference (a minus the others)",
                    choices=CSG_OPERATIONS),
             Option("blend", "float", 0.0, "blend radius in mm of the smooth variant (0: sharp)", minimum=0.0),
             Option("iso", "float", None, "isovalue of volume inputs in their units (default: 300 HU for CT, else "
                    "35 % into the value range)"),
             ) + _GRID_OPTIONS + _DISTANCE_OPTIONS,
))
