"""Checks of our output against references: surfaces, images and voxel-face coverage. Imports only
:mod:`algorithms.common`, so every family's tests and reports can use it.

- :mod:`.triangles`: the surface adapter (:func:`surface_arrays`, :func:`triangulated`) and
  :func:`same_triangles`.
- :mod:`.measures`: :func:`surface_area`, :func:`enclosed_volume`, :func:`distance_to_surface`,
  :func:`hausdorff`.
- :mod:`.topology`: :func:`edge_manifoldness`, :func:`is_watertight`, :func:`is_manifold`,
  :func:`connected_components`, :func:`orientation_outward`, :func:`ray_crossings`.
- :mod:`.image_metrics`: PSNR, RMSE, SSIM, difference images and heat maps, shading banding.
- :mod:`.voxel_surfaces`: exact voxel-face coverage and memory as source 000 counts it.

The names of :mod:`.triangles`, :mod:`.measures` and :mod:`.topology` are re-exported here.
"""

from .measures import SurfaceDistance, distance_to_surface, enclosed_volume, hausdorff, signed_volumes, surface_area
from .topology import (
    EdgeReport,
    OrientationReport,
    connected_components,
    edge_manifoldness,
    is_manifold,
    is_watertight,
    orientation_outward,
    ray_crossings,
)
from .triangles import TriangleSetComparison, corners, same_triangles, surface_arrays, triangulated

__all__ = [
    "EdgeReport",
    "OrientationReport",
    "SurfaceDistance",
    "TriangleSetComparison",
    "connected_components",
    "corners",
    "distance_to_surface",
    "edge_manifoldness",
    "enclosed_volume",
    "hausdorff",
    "is_manifold",
    "is_watertight",
    "orientation_outward",
    "ray_crossings",
    "same_triangles",
    "signed_volumes",
    "surface_area",
    "surface_arrays",
    "triangulated",
]
