"""``voxelscope mesh VOLUME.zarr --workers N`` / ``--scheduler ADDRESS``: the chunked path of the mesh command.

The command module (:mod:`app.cli.mesh`) hands over here when either flag is given (this module imports dask and
distributed, so only then); this opens the store's
metadata only, starts or connects to the cluster (:func:`.cluster.dask_client`), meshes chunk by chunk
(:func:`.chunked.mesh_chunked`), moves the stitched mesh to patient coordinates and writes it with the same
clean-up, validation, sidecar and JSON report as the in-memory path (plus a ``chunked`` entry: blocks, skipped
blocks, workers, seconds). The client holds the mesh, never the samples.
"""

from __future__ import annotations

import time

from algorithms.common.progress import scaled
from algorithms.surfaces.marching_cubes import MarchingCubesMesh

from ..distributed.chunked import mesh_chunked
from ..distributed.cluster import dask_client
from ..io.zarr import is_zarr_path, open_zarr
from ..mesh_cleanup import Cleanup
from ..mesh_files import check_mesh_targets
from ..meshing import SurfaceForExport, to_world, write_export
from ..volume import default_isovalue
from ..samples import resolve_path
from .common import CommandError, print_json

__all__ = ["run_chunked_mesh"]


def _refuse(args, tools) -> None:
    if tools or getattr(args, "labels", None) is not None:
        raise CommandError("--workers/--scheduler mesh one surface of a chunked volume; --cut and --labels need the "
                           "volume in memory (drop --workers to read it whole)")
    if args.method != "marching-cubes":
        raise CommandError(f"--workers/--scheduler run our marching cubes chunk by chunk; --method {args.method} "
                           "runs in memory only (use --method marching-cubes)")
    if args.stride != 1 or args.close_edges:
        raise CommandError("--stride and --close-edges are not available chunk by chunk; drop them or --workers")


def run_chunked_mesh(args, tools, cleanup: Cleanup, *, progress=None) -> int:
    """Run the chunked mesh command for parsed ``args``; returns the exit code."""
    _refuse(args, tools)
    path = resolve_path(args.path)
    if not is_zarr_path(path):
        raise CommandError(f"{path}: --workers/--scheduler read a chunked Zarr/OME-Zarr store; convert the volume "
                           "first with 'voxelscope convert VOLUME -o VOLUME.zarr'")
    chunked = open_zarr(path)
    value_range = chunked.metadata.get("value_range")
    if args.iso is not None:
        iso = float(args.iso)
    elif chunked.units == "HU" or value_range:
        iso = default_isovalue(chunked.units, value_range)  # the store's range: its percentiles would read it all
    else:
        raise CommandError(f"{path}: give --iso (the store records no value range to choose a default from)")
    if value_range and not value_range[0] < iso <= value_range[1]:
        raise CommandError(f"{path}: no surface at {iso:g} {chunked.units_label} (the values run from "
                           f"{value_range[0]:g} to {value_range[1]:g}); choose an isovalue inside that range")
    output = check_mesh_targets(args.output, overwrite=args.force)
    started = time.perf_counter()
    workers = None if args.workers == -1 else args.workers  # bare --workers: the machine's cores
    with dask_client(workers=workers, scheduler=args.scheduler) as client:
        cluster_seconds = time.perf_counter() - started
        result = mesh_chunked(chunked, iso, client=client, progress=scaled(progress, 0.0, 0.6))
    stats = {**result.stats, "cluster_seconds": cluster_seconds}
    if result.triangles.shape[0] == 0:
        raise CommandError(f"{path}: no surface at {iso:g} {chunked.units_label}; choose another isovalue")
    mesh = MarchingCubesMesh(result.points, result.triangles, None, None)
    del result
    polydata = mesh.to_polydata()
    del mesh
    world = to_world(polydata, chunked, args.coordinates)
    del polydata
    source = {"source_file": str(path), "source_format": chunked.metadata.get("source_format", "Zarr"),
              "series_uid": "", "modality": chunked.modality, "value_units": chunked.units_label}
    seconds = time.perf_counter() - started
    surface_stats = {"points": int(world.GetNumberOfPoints()), "triangles": int(world.GetNumberOfPolys()),
                     "cells": int(world.GetNumberOfCells()), "strips": 0, "bytes": 0, "seconds": seconds}
    surface = SurfaceForExport(world, surface_stats, source, "marching-cubes", iso, args.coordinates.upper(),
                               {"chunked": True, "chunks": stats["chunks"], "workers": stats["workers"],
                                "scheduler": args.scheduler or "local"})
    export = write_export(surface, output, cleanup=cleanup, overwrite=args.force, progress=scaled(progress, 0.6, 1.0))
    validity = export.validity or {}
    report = {
        "points": surface_stats["points"], "triangles": surface_stats["triangles"], "cells": surface_stats["cells"],
        "strips": 0, "seconds": seconds, "method": "marching-cubes", "iso": iso, "iso_units": chunked.units_label,
        "coordinates": args.coordinates.upper(), "output": str(export.paths[0]),
        "sidecar": str(export.paths[1]) if len(export.paths) > 1 else None,
        "written": {k: int(v) for k, v in export.written.items()}, "validity": validity, "chunked": stats,
    }
    if args.json:
        print_json(report)
        return 0
    print(f"Meshed {stats['blocks_meshed']} of {stats['blocks']} chunks ({stats['blocks_skipped']} skipped: no "
          f"surface) on {stats['workers']} workers in {seconds:.1f} s: {report['triangles']} triangles, "
          f"{report['points']} points at {iso:g} {chunked.units_label}")
    print(f"Wrote {report['output']} ({report['coordinates']} mm) and {report['sidecar']}")
    return 0
