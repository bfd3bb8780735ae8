"""What every algorithm family shares. Imports only NumPy, numba, SciPy and VTK (never another family).

- :mod:`.progress`: progress callbacks and cancellation (``ProgressCallback``, ``OperationCancelled``).
- :mod:`.vtk_bridge`: running VTK algorithms (``run_algorithm``, ``VTKError``) and converting arrays to and from
  VTK images, polydata, cell arrays and matrices; the axis-order conventions.
- :mod:`.validation`: the input checks of every core (volumes, geometry, isovalues, counts, distances, sizes).
- :mod:`.camera`, :mod:`.transfer`, :mod:`.render_result`: camera, transfer table and frame of the software
  renderers; :mod:`.sampling` and :mod:`.pixel_rays`: their shared numba kernels; :mod:`.render_filter`: their
  VTK filter base (volume in, RGBA image out).
- :mod:`.mesh`: the mesh types our algorithms return (triangles, strips, tetrahedra).

Nothing is imported here, so ``import algorithms.common.progress`` stays light.
"""
