"""Marching cubes with Paul Bourke's tables (source 001), indexed and oriented like ``vtkMarchingCubes``.

- :mod:`.core`: :func:`marching_cubes`, its result :class:`MarchingCubesMesh`, and :func:`count_triangles`.
- :mod:`.kernels`: the numba passes (counting per row of cells, filling triangles and vertices, merging).
- :mod:`.tables`: Bourke's edge and triangle tables.
- :mod:`.filter`: :class:`MarchingCubesFilter`.
- :mod:`.blocks`: :func:`marching_cubes_block`, one block of a larger volume with global edge keys (chunked meshing).
"""

from .blocks import BlockMesh, marching_cubes_block
from .core import MarchingCubesMesh, count_triangles, marching_cubes
from .filter import MarchingCubesFilter

__all__ = ["BlockMesh", "MarchingCubesFilter", "marching_cubes_block", "MarchingCubesMesh", "count_triangles", "marching_cubes"]
