"""Generalised winding numbers of open or self-intersecting meshes (Jacobson et al. 2013), with a hierarchical
far-field approximation (Barill et al. 2018), for ``voxelise(..., inside="winding")``.

- :mod:`.core`: the exact sum (:func:`solid_angle_winding`), the tree (:class:`WindingTree`,
  :func:`winding_numbers`) and the fans that close a mesh's boundary (:func:`boundary_caps`).
- :mod:`.blocks`: thresholding the fans' winding number over cubes of voxels, coarse to fine.
"""

from .core import (DEFAULT_BETA, LEAF_SIZE, BoundaryCaps, WindingTree, boundary_caps, solid_angle_winding,
                   tree_solid_angle, winding_numbers)

__all__ = ["BoundaryCaps", "DEFAULT_BETA", "LEAF_SIZE", "WindingTree", "boundary_caps", "solid_angle_winding",
           "tree_solid_angle", "winding_numbers"]
