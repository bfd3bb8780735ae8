"""``voxelscope info``: describe a volume (size, spacing, LPS geometry, values, series) or a mesh (counts, closed,
manifold, orientation, bounds)."""

from __future__ import annotations

from .common import add_input_arguments, load_item, print_json

NAME = "info"
HELP = "describe a volume (size, spacing, LPS geometry, values, series) or a mesh (counts, closed, orientation)"
ORDER = 10


def add_arguments(parser) -> None:
    add_input_arguments(parser, meshes=True)
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args) -> int:
    from ..io.zarr import is_zarr_path
    from ..samples import SAMPLES, resolve_path, sample_name

    if is_zarr_path(resolve_path(args.path)):  # chunked volumes: metadata only, no sample read (issue 19)
        return _chunked_info(args)
    item = load_item(args)
    facts = item.describe()
    facts.pop("name", None)
    sample = SAMPLES.get(sample_name(args.path) or "")
    if sample is not None:
        facts["sample"] = sample.description
    if item.kind == "volume":
        volume = item.volume
        facts.pop("kind", None)
        if volume.metadata.get("series_uid"):
            facts["series_uid"] = volume.metadata["series_uid"]
        if "other_series" in volume.metadata:
            facts["other_series"] = volume.metadata["other_series"]
    if args.json:
        print_json(facts)
        return 0
    print("\n".join(_volume_lines(item, facts) if item.kind == "volume" else _mesh_lines(item, facts)))
    return 0


def _volume_lines(item, facts) -> list[str]:
    volume = item.volume
    units = volume.units_label
    lines = [f"Sample       {facts['sample']}"] if "sample" in facts else []
    lines += [
        f"Source       {volume.metadata.get('source_path', '')} ({facts['source_format']})",
        f"Dimensions   {' x '.join(map(str, facts['dimensions']))} voxels (x, y, z)",
        f"Spacing      {' x '.join(f'{s:g}' for s in facts['spacing'])} mm",
        f"Origin       ({', '.join(f'{o:.3f}' for o in facts['origin'])}) mm LPS",
        "Direction    " + "  ".join(
            "(" + ", ".join(f"{v:+.4f}" for v in volume.direction[:, c]) + f") {label}"
            for c, label in zip(range(3), ("i", "j", "k"))
        ) + f"   axes point to {'/'.join(volume.axis_labels())}",
        f"Bounds       x {facts['world_bounds'][0]:.2f} to {facts['world_bounds'][1]:.2f}, "
        f"y {facts['world_bounds'][2]:.2f} to {facts['world_bounds'][3]:.2f}, "
        f"z {facts['world_bounds'][4]:.2f} to {facts['world_bounds'][5]:.2f} mm LPS",
        f"Values       {facts['dtype']}, {facts['range'][0]:g} to {facts['range'][1]:g} {units}",
        f"Modality     {facts['modality'] or 'unknown'}",
    ]
    if facts.get("series_uid"):
        lines.append(f"Series       {facts['series_uid']}  {volume.metadata.get('series_description', '')}".rstrip())
    for other in facts.get("other_series", []):
        lines.append(f"Not used     series {other['series_uid']} ({other['description'] or 'no description'}, "
                     f"{other['slices']} images): {other['reason']}")
    for warning in facts["warnings"]:
        lines.append(f"Warning      {warning}")
    return lines


def _chunked_info(args) -> int:
    from ..io.zarr import open_zarr
    from ..samples import resolve_path

    facts = open_zarr(resolve_path(args.path)).describe()
    facts.pop("kind", None)
    if args.json:
        print_json(facts)
        return 0
    value_range = facts["range"]
    print(f"Source       {resolve_path(args.path)} ({facts['source_format']})")
    print(f"Dimensions   {' x '.join(map(str, facts['dimensions']))} voxels (x, y, z), "
          f"{facts['bytes'] / 2**30:.2f} GiB of {facts['dtype']}")
    print(f"Spacing      {' x '.join(f'{s:g}' for s in facts['spacing'])} mm")
    print(f"Origin       ({', '.join(f'{o:.3f}' for o in facts['origin'])}) mm LPS")
    print("Values       " + (f"{value_range[0]:g} to {value_range[1]:g}" if value_range else "not recorded"))
    for n, level in enumerate(facts["levels"]):
        print(f"Level {n}      {' x '.join(map(str, level['dimensions']))} voxels, chunks "
              f"{' x '.join(map(str, level['chunks']))}, {' x '.join(f'{s:g}' for s in level['spacing'])} mm")
    for warning in facts["warnings"]:
        print(f"Warning      {warning}")
    return 0


def _mesh_lines(item, facts) -> list[str]:
    bounds = facts["bounds"]
    volume = facts.get("volume_mm3")
    lines = [
        f"Source       {item.metadata.get('source_path', '')} ({facts.get('source_format', 'mesh')})",
        f"Counts       {facts['points']:,} points, {facts['triangles']:,} triangles, {facts['components']} "
        f"connected component(s)",
        f"Closed       {'yes' if facts['closed'] else 'no'} ({facts['boundary_edges']:,} boundary edges, "
        f"{facts['non_manifold_edges']:,} non-manifold edges)",
        f"Orientation  {facts['orientation']}",
        f"Bounds       x {bounds[0]:.6g} to {bounds[1]:.6g}, y {bounds[2]:.6g} to {bounds[3]:.6g}, "
        f"z {bounds[4]:.6g} to {bounds[5]:.6g} mm",
        f"Area         {facts['area_mm2']:.6g} mm^2" + (f", enclosed volume {volume:.6g} mm^3" if volume is not None
                                                      else " (no enclosed volume: the mesh is not closed and oriented)"),
    ]
    for warning in facts.get("warnings", []):
        lines.append(f"Warning      {warning}")
    return lines
