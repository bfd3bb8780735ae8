"""Operations that make surface meshes: the isosurface of a volume or field as a mesh of the scene (patient
coordinates), by any surface mode."""

from __future__ import annotations

from typing import Any, Mapping

from ..modes import get_mode, mode_names
from ..options import Option
from . import register_operation
from .base import Input, Operation, OperationResult


class ExtractSurface(Operation):
    """A volume's (or field's) isosurface, extracted by a surface mode, as a mesh item in LPS mm."""

    def run(self, items: Mapping[str, Any], options: Mapping[str, Any], *, progress=None) -> OperationResult:
        from ..meshing import EmptySurfaceError, check_isovalue, merge_duplicate_points, to_world
        from ..volume import default_iso
        from ..scene import MeshItem

        source = items["volume"]
        volume = source.volume
        iso = options["iso"]
        if iso is None:
            iso = source.iso if source.kind == "field" else default_iso(volume)
        method = get_mode(options["method"])
        if method.output != "surface" or method.input != "volume":
            raise ValueError(f"{method.name!r} does not extract surfaces from volumes")
        check_isovalue(volume, float(iso), source.name)
        result = method.extract(source, iso, progress=progress)
        if result.stats["triangles"] == 0:
            lo, hi = volume.value_range
            raise EmptySurfaceError(f"{source.name}: no surface at {iso:g} {volume.units_label} (its values run from "
                                    f"{lo:g} to {hi:g}); choose an isovalue inside that range")
        world = to_world(result.polydata, volume, "LPS")
        if not method.unique_points:
            world = merge_duplicate_points(world)
        name = f"{source.name} surface {iso:g} {volume.units_label}"
        item = MeshItem(name, polydata=world, metadata={"source": source.name, "method": method.name, "iso": iso})
        return OperationResult(item, {**result.stats, "iso": iso, "method": method.name})


register_operation(ExtractSurface(
    "extract-surface", "Extract surface as a mesh", "The isosurface of a volume or field as a mesh of the scene "
    "(LPS mm), by any surface method", inputs=(Input("volume", ("volume", "field"), "the volume or field"),),
    output="mesh", group="Surfaces",
    options=(
        Option("method", "str", "flying-edges", "surface method (a surface mode)",
               choices=lambda: tuple(mode_names(input="volume", output="surface"))),
        Option("iso", "float", None, "isovalue in the volume's units (default: 300 HU for CT, 0 mm for distance "
               "fields, 0.5 for masks, else 35 % into the value range)"),
    ),
))
