"""Mesh voxelisation (source 002, section 2.2): a closed triangle mesh to a binary mask on any grid, slice by slice
and row by row, by parity or, for open and self-intersecting meshes, by the generalised winding number.

- :mod:`.core`: :func:`voxelise`, :func:`voxelise_with_report` and its :class:`VoxelisationReport`.
- :mod:`.kernels`: the numba passes (triangles binned into slices, row crossings, filling).
- :mod:`.predicates`: exact orientation signs with simulation of simplicity, for the crossing decisions.
- :mod:`.filter`: :class:`VoxeliseFilter` and the grid of a ``vtkImageData``.
"""

from .core import INSIDE_RULES, VoxelisationReport, voxelise, voxelise_with_report, warm_up
from .filter import VoxeliseFilter, grid_of_image, image_on_grid

__all__ = ["INSIDE_RULES", "VoxelisationReport", "VoxeliseFilter", "grid_of_image", "image_on_grid", "voxelise",
           "voxelise_with_report", "warm_up"]
