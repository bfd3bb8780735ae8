"""Isosurface stuffing (Labelle & Shewchuk 2007; source 002, chapter 4): tetrahedral meshes with guaranteed dihedral
angles filling an isosurface of a volume or a distance field.

- :mod:`.core`: :func:`isosurface_stuffing` (volume, isovalue, lattice spacing -> :class:`StuffingResult`);
- :mod:`.lattice`: the BCC lattice, its data layout and memory; :mod:`.stencils`: the stencil table and the parity
  rule; :mod:`.kernels`, :mod:`.fill`: the numba kernels; :mod:`.filter`: the VTK filter
  (``vtkImageData`` -> ``vtkUnstructuredGrid``).
"""

from .core import ALPHAS, ANGLE_BOUNDS, StuffingResult, isosurface_stuffing, resolve_alphas, stuffing_table

__all__ = ["ALPHAS", "ANGLE_BOUNDS", "StuffingResult", "isosurface_stuffing", "resolve_alphas", "stuffing_table"]
