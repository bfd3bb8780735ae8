"""Fields on a grid made from meshes and volumes: masks, distances, constructive solid geometry, cut-away tools.

Modules are imported on use (no eager imports here: each pulls in its own numba kernels).

One package per algorithm, like :mod:`algorithms.surfaces` and :mod:`algorithms.rendering`:

- :mod:`.voxelise`: closed triangle meshes to binary masks, slice by slice and row by row (source 002, section
  2.2), :func:`~.voxelise.voxelise` and the ``VoxeliseFilter``; exact crossing decisions by simulation of
  simplicity (:mod:`.voxelise.predicates`, :mod:`.voxelise.kernels`).
- :mod:`.winding`: generalised winding numbers of open or self-intersecting meshes (Jacobson et al. 2013) with a
  hierarchical far-field approximation (Barill et al. 2018), for ``voxelise(..., inside="winding")``.
- :mod:`.distance`: signed distance fields of meshes, exact in a band (source 002, chapter 3), propagated outside
  it (``DistanceFieldFilter``, and ``CsgFilter`` for :mod:`.csg`).
- :mod:`.csg`: constructive solid geometry on distance fields (one module).
- :mod:`.cutaway_tools`: the cut-away tools as fields (one module).
"""
