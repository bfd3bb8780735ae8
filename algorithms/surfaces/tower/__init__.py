"""The tower algorithm of source 000: visible voxel faces as triangle strips, and its hybrid with indexed triangles.

- :mod:`.core`: :func:`tower_strips`, :func:`hybrid` and their results :class:`TowerStrips`, :class:`HybridSurface`.
- :mod:`.kernels`: the numba walk over slices (circumference loops, top and bottom runs).
- :mod:`.filter`: :class:`TowerFilter`, :class:`HybridFilter`.
"""

from .core import STRIP_BOTTOM, STRIP_CIRCUMFERENCE, STRIP_TOP, HybridSurface, TowerStrips, hybrid, tower_strips
from .filter import HybridFilter, TowerFilter

__all__ = [
    "STRIP_BOTTOM",
    "STRIP_CIRCUMFERENCE",
    "STRIP_TOP",
    "HybridFilter",
    "HybridSurface",
    "TowerFilter",
    "TowerStrips",
    "hybrid",
    "tower_strips",
]
