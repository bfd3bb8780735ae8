"""Signed distance fields of triangle meshes (source 002, chapter 3): exact in a band around the surface, propagated
or clamped outside it, signed by voxelisation.

- :mod:`.core`: :func:`signed_distance` and its :class:`DistanceField`, the band (:func:`band_distances`,
  :func:`band_from_percent`) and brute-force :func:`exact_distances`.
- :mod:`.characteristics`: the polytopes around each face, edge and vertex (Mauch's characteristics).
- :mod:`.kernels`, :mod:`.scan`: distances to the features, and the scan conversion of the polytopes into the grid.
- :mod:`.propagate`, :mod:`.feature_transform`: the field outside the band.
- :mod:`.filter`: ``DistanceFieldFilter`` and ``CsgFilter`` (CSG by :mod:`algorithms.fields.csg`).
"""

from .core import (MAX_SLICE_ENTRIES, OUTSIDE_RULES, REGIONS, BandDistances, DistanceField, MeshFrames,
                   band_distances, band_from_percent, exact_distances, signed_distance)
from .filter import CsgFilter, DistanceFieldFilter

__all__ = ["BandDistances", "CsgFilter", "DistanceField", "DistanceFieldFilter", "MAX_SLICE_ENTRIES", "MeshFrames",
           "OUTSIDE_RULES", "REGIONS", "band_distances", "band_from_percent", "exact_distances", "signed_distance"]
