"""Voxelscope's algorithm cores (NumPy/numba) and their thin VTK filter wrappers. No Qt, no application state.

The algorithms are grouped by what they take and give (families); a family imports only :mod:`.common` and
:mod:`.compare`, never another family (an import-linter contract in ``pyproject.toml`` checks it):

- :mod:`.common`: what every family shares: progress and cancellation, the NumPy-VTK bridge, input validation,
  camera, transfer tables, rendered frames, sampling and pixel-ray kernels, the renderer filter base, and the mesh
  types (triangle meshes, triangle strips, tetrahedral meshes).
- :mod:`.surfaces`: volume -> surface: visible voxel faces and the tower strips (source 000), marching cubes
  (source 001).
- :mod:`.rendering`: volume -> image: ray marching (sources 001, 002), texture slicing (sources 001, 002),
  shear-warp (source 004).
- :mod:`.compare`: the checks: triangle-set comparison, measures, topology, image metrics, voxel-face coverage.
- :mod:`.references`: the VTK built-ins we compare against (contouring, voxel faces, strips, volume mappers).
- :mod:`.datasets`: synthetic volumes and fields for tests and benchmarks.

Every module names its method and cites its source by the short names of ``docs/references.md`` ("source 000"
... "source 004", with author and title where the document names them) and the original papers.
"""

import importlib

from .common import kernel_cache

# Compiled kernels live in a per-user folder shared by checkouts of the same sources (see common/kernel_cache.py);
# registered before any kernel module is imported.
kernel_cache.install()

# Public names and the module that defines each. They are imported on first use (PEP 562), like scikit-image's
# lazy loading, so ``import algorithms.common.progress`` does not pull numba and every renderer into a short
# command.
_EXPORTS = {
    "Camera": "common.camera", "TransferTable": "common.transfer", "RenderResult": "common.render_result",
    "TriangleMesh": "common.mesh", "TriangleStrips": "common.mesh", "TetMesh": "common.mesh",
    "voxel_faces": "surfaces.voxel_faces", "VoxelFaces": "surfaces.voxel_faces",
    "VoxelFacesFilter": "surfaces.voxel_faces",
    "tower_strips": "surfaces.tower", "hybrid": "surfaces.tower", "TowerStrips": "surfaces.tower",
    "HybridSurface": "surfaces.tower", "TowerFilter": "surfaces.tower", "HybridFilter": "surfaces.tower",
    "marching_cubes": "surfaces.marching_cubes", "MarchingCubesMesh": "surfaces.marching_cubes",
    "MarchingCubesFilter": "surfaces.marching_cubes",
    "raymarch": "rendering.raymarch", "RaymarchRenderer": "rendering.raymarch", "RaymarchFilter": "rendering.raymarch",
    "slice_polygons": "rendering.texture_slicing", "SlicingRenderer": "rendering.texture_slicing",
    "SliceStackProp": "rendering.texture_slicing", "TextureSlicingFilter": "rendering.texture_slicing",
    "factorize": "rendering.shear_warp", "ShearWarpRenderer": "rendering.shear_warp",
    "ShearWarpFilter": "rendering.shear_warp",
    "compare_images": "compare.image_metrics", "ImageComparison": "compare.image_metrics",
    "psnr": "compare.image_metrics", "psnr_foreground": "compare.image_metrics", "ssim": "compare.image_metrics",
    "same_triangles": "compare", "hausdorff": "compare", "surface_area": "compare", "enclosed_volume": "compare",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'algorithms' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
