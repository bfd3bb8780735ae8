"""Tetrahedral meshing: volume or field -> tetrahedral mesh. Imports only :mod:`algorithms.common` and
:mod:`algorithms.compare`.

- :mod:`.isosurface_stuffing`: isosurface stuffing (Labelle & Shewchuk 2007; source 002, chapter 4), on a uniform lattice
  (the paper's octree-graded variant is not built yet).
"""
