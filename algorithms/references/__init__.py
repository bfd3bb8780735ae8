"""The VTK built-ins we compare our algorithms against, in one place, run the way we run our own filters.

- :mod:`.vtk_surfaces`: isosurfaces (``vtkFlyingEdges3D``, ``vtkMarchingCubes``), voxel faces (``vtkThreshold``
  + ``vtkDataSetSurfaceFilter``) and strips (``vtkStripper``).
- :mod:`.vtk_volume_mappers`: GPU and CPU ray casting (``vtkGPUVolumeRayCastMapper``,
  ``vtkFixedPointVolumeRayCastMapper``) with a fixed sample distance.
"""
