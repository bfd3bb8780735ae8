"""Meshing volumes larger than memory on a Dask cluster (issue 19).

- :mod:`.cluster`: :func:`dask_client` - a ``LocalCluster`` of N worker processes, or any scheduler address.
- :mod:`.chunked`: :func:`mesh_chunked` - our marching cubes per chunk of a Zarr/OME-Zarr volume as Dask tasks
  (:func:`algorithms.surfaces.marching_cubes.blocks.marching_cubes_block`), chunks the surface cannot cross
  skipped, progress from the finished tasks, cancel by the progress callback.
- :mod:`.stitch`: :class:`Stitcher` - merges the pieces by their global edge keys as they arrive.
"""

from .chunked import ChunkedMesh, mesh_chunked
from .cluster import dask_client
from .stitch import Stitcher

__all__ = ["ChunkedMesh", "Stitcher", "dask_client", "mesh_chunked"]
