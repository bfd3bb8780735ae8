"""Benchmarks: ours against VTK's built-ins in the same run, medians over repeats, CSV plus plots.

Each benchmark module exposes ``run(out_dir, *, quick=False, progress=None) -> list[pathlib.Path]`` (the files it
wrote) and is started by ``voxelscope bench NAME -o DIR``. Speed is measured here, never asserted in unit tests.
"""

BENCHMARKS = {
    "voxel-surfaces": "app.bench.voxel_surfaces",
    "cutaway": "app.bench.cutaway",
    "distance": "app.bench.distance",
    "chunked": "app.bench.chunked",
    "marching-cubes": "app.bench.marching_cubes",
    "memory": "app.bench.memory",
    "render": "app.bench.render",
    "shear-warp": "app.bench.shear_warp",
    "tetmesh": "app.bench.tetmesh",
    "voxelise": "app.bench.voxelise",
    "compile": "app.bench.compile",
}
