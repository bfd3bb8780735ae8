"""Fields on a grid made from meshes and volumes: masks, distances, constructive solid geometry, selections.

Modules are imported on use (no eager imports here: each pulls in its own numba kernels).

- :mod:`.voxelise`: closed triangle meshes to binary masks, slice by slice and row by row (source 002, section
  2.2), :func:`~.voxelise.voxelise` and the ``VoxeliseFilter``; exact crossing decisions by simulation of
  simplicity (:mod:`._predicates`, :mod:`._voxelise_kernels`).
- :mod:`.winding`: generalised winding numbers of open or self-intersecting meshes (Jacobson et al. 2013) with a
  hierarchical far-field approximation (Barill et al. 2018), for ``voxelise(..., inside="winding")``.
- :mod:`.distance`, :mod:`.propagate`, :mod:`.csg`, :mod:`.distance_filter`: signed distance fields of meshes, exact
  in a band (source 002, chapter 3), propagated outside it, and CSG on them (``DistanceFieldFilter``, ``CsgFilter``).
"""
