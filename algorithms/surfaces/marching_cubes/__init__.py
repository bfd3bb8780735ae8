"""Marching cubes with Paul Bourke's tables (source 001), indexed and oriented like ``vtkMarchingCubes``.

- :mod:`.core`: :func:`marching_cubes` and its result :class:`MarchingCubesMesh`.
- :mod:`.kernels`: the numba passes (classification, vertex numbering, triangles, vertex attributes).
- :mod:`.tables`: Bourke's edge and triangle tables.
- :mod:`.filter`: :class:`MarchingCubesFilter`.
"""

from .core import MarchingCubesMesh, marching_cubes
from .filter import MarchingCubesFilter

__all__ = ["MarchingCubesFilter", "MarchingCubesMesh", "marching_cubes"]
