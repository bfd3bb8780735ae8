"""Surface methods: volume in, triangle mesh or strips out.

- :mod:`.voxel_faces`: every visible voxel face as two triangles (source 000's baseline).
- :mod:`.tower`: the same faces as triangle strips (source 000's tower algorithm) and the hybrid of both.
- :mod:`.marching_cubes`: isosurfaces with Bourke's tables (source 001).

Results are the mesh types of :mod:`algorithms.common.mesh`. A family imports only :mod:`algorithms.common` and
:mod:`algorithms.compare`, never another family.
"""
