"""Voxelscope's algorithm cores (NumPy/numba) and their thin VTK filter wrappers. No Qt, no application state.

Every module names its method, its source document in ``../shared/seeds/`` and the original paper:

- :mod:`.voxel_faces`, :mod:`.tower`: visible voxel faces and the tower triangle strips (source 000)
- :mod:`.marching_cubes`: marching cubes with Bourke's case tables (source 001)
- :mod:`.raymarch`: ray-marched volume rendering, Beer-Lambert absorption, shading, scattering (sources 001, 002)
- :mod:`.texture_slicing`: view- and axis-aligned texture slicing (sources 001, 002)
- :mod:`.shear_warp`: shear-warp with run-length encoding and early termination (source 004)
- :mod:`.surface_compare`, :mod:`.image_metrics`, :mod:`.voxel_surface_checks`: the comparison toolkits
- :mod:`.camera`, :mod:`.transfer`, :mod:`.render_result`: what the renderers share
"""

import importlib

# Public names and the module that defines each. They are imported on first use (PEP 562), like scikit-image's
# lazy loading, so ``import algorithms._vtk`` does not pull numba and every renderer into a short command.
# Functions named like their module (voxel_faces, marching_cubes, raymarch) are not re-exported: the package
# attribute of that name is the submodule once it is imported; use ``from algorithms.marching_cubes import
# marching_cubes``.
_EXPORTS = {
    "Camera": "camera", "TransferTable": "transfer", "RenderResult": "render_result",
    "VoxelFaces": "voxel_faces", "VoxelFacesFilter": "voxel_faces",
    "tower_strips": "tower", "hybrid": "tower", "TriangleStrips": "tower", "HybridSurface": "tower",
    "TowerFilter": "tower", "HybridFilter": "tower",
    "MarchingCubesMesh": "marching_cubes",
    "MarchingCubesFilter": "marching_cubes",
    "RaymarchRenderer": "raymarch", "RaymarchFilter": "raymarch",
    "slice_polygons": "texture_slicing", "SlicingRenderer": "texture_slicing", "SliceStackProp": "texture_slicing",
    "TextureSlicingFilter": "texture_slicing",
    "factorize": "shear_warp", "ShearWarpRenderer": "shear_warp", "ShearWarpFilter": "shear_warp",
    "compare_images": "image_metrics", "ImageComparison": "image_metrics", "psnr": "image_metrics",
    "psnr_foreground": "image_metrics", "ssim": "image_metrics",
    "same_triangles": "surface_compare", "hausdorff": "surface_compare", "surface_area": "surface_compare",
    "enclosed_volume": "surface_compare",
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
