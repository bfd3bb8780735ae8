"""Frame times of the software renderers' kernels of one checkout, for before/after comparisons of a kernel change.

Usage (from any directory, with the project's virtual environment)::

    python scripts/kernel-timings.py CHECKOUT [--frames N] [--csv FILE]

imports ``algorithms`` and ``app`` from ``CHECKOUT`` (so two checkouts, e.g. a ``git worktree`` of the commit before
a change and the working tree, run the same script), renders the CT phantom (256 x 256 x 88 voxels of 1.094 x 1.094
x 3 mm, ``ct-bone``, 512 x 512 pixels) with every shear-warp kernel path - parallel run-length compositing unshaded
and shaded, perspective scanlines, jittered post-classification, cut-away tools (a sphere and a grid tool, binary
and distance evaluation) - and, at 256 x 256 pixels, the ray marcher and texture slicing (trilinear sampling, and the
ray marcher with the grid tool) over ``N`` frames of a turning camera after one warm-up frame (numba's cache load),
and prints one line per case with the median frame time and the set-up time (classification, run-length encoding,
normals) in milliseconds. Times are wall-clock seconds of one
``render`` call. Run the two checkouts in turns (docs/testing.md shows the loop) and compare the medians; nothing here
asserts anything.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", type=Path, help="the project checkout whose kernels are timed")
    parser.add_argument("--frames", type=int, default=10, help="timed frames per case (default 10)")
    parser.add_argument("--csv", type=Path, help="also append one row per case to this CSV file")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(args.checkout.resolve()))

    import numpy as np

    from algorithms.common.grid import Grid
    from algorithms.fields.cutaway_tools import grid_tool, sphere_tool, tool_set
    from algorithms.rendering.raymarch import RaymarchRenderer
    from algorithms.rendering.shear_warp import ShearWarpRenderer
    from algorithms.rendering.texture_slicing import SlicingRenderer
    from app.datasets import ct_head_phantom
    from app.pipeline import default_camera
    from app.transfer import transfer_function_for

    volume = ct_head_phantom(shape=(88, 256, 256))
    table = transfer_function_for(volume, "ct-bone").to_table(volume.value_range)
    to_volume = np.linalg.inv(volume.local_to_world)

    def cameras(parallel: bool):
        return [default_camera(volume, azimuth=30 + 25 * frame, elevation=15, parallel=parallel).transformed(to_volume)
                for frame in range(args.frames + 1)]

    grid = Grid.around([-40, 40, -40, 40, -40, 40], voxels=40, padding=2)
    k, j, i = np.indices(grid.shape)
    world = grid.index_to_world(np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)).reshape(grid.shape + (3,))
    placed = [sphere_tool((20.0, -60.0, 20.0), 45.0), grid_tool(np.linalg.norm(world, axis=-1) < 35.0, grid)]
    binary = tool_set(placed, volume.local_to_world, evaluation="binary", width=min(volume.spacing))
    distance = tool_set(placed, volume.local_to_world, evaluation="distance", width=min(volume.spacing))

    # name: (renderer, its options, parallel projection, cut-away tools, image size in pixels)
    cases = {
        "parallel": (ShearWarpRenderer, dict(), True, None, 512),
        "parallel-shaded": (ShearWarpRenderer, dict(shading=True), True, None, 512),
        "own-grid": (ShearWarpRenderer, dict(resample_spacing=None), True, None, 512),
        "perspective": (ShearWarpRenderer, dict(), False, None, 512),
        "jitter": (ShearWarpRenderer, dict(jitter=True), True, None, 512),
        "tools-binary": (ShearWarpRenderer, dict(shading=True), True, binary, 512),
        "tools-distance": (ShearWarpRenderer, dict(shading=True), True, distance, 512),
        "raymarch": (RaymarchRenderer, dict(), False, None, 256),
        "raymarch-tools": (RaymarchRenderer, dict(), False, distance, 256),
        "slicing": (SlicingRenderer, dict(), False, None, 256),
    }
    rows = []
    for name, (kind, options, parallel, tools, size) in cases.items():
        start = time.perf_counter()
        renderer = kind(volume.array, volume.spacing, table, **options)
        setup_ms = 1000.0 * (time.perf_counter() - start)
        times = []
        for index, camera in enumerate(cameras(parallel)):
            start = time.perf_counter()
            renderer.render(camera, size, size, tools=tools)
            if index:  # the first frame loads numba's cache
                times.append(time.perf_counter() - start)
        median_ms = 1000.0 * statistics.median(times)
        rows.append({"checkout": str(args.checkout), "case": name, "frames": len(times), "median_ms": median_ms,
                     "setup_ms": setup_ms})
        print(f"{name:16s} {median_ms:8.2f} ms (median of {len(times)} frames), set-up {setup_ms:8.1f} ms")
    if args.csv:
        new = not args.csv.exists()
        with args.csv.open("a", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            if new:
                writer.writeheader()
            writer.writerows(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
