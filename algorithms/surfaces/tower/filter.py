"""VTK filters of the tower algorithm and its hybrid: ``vtkImageData`` in, ``vtkPolyData`` strips (and triangles) out.

Thin wrappers around :func:`.core.tower_strips` and :func:`.core.hybrid`; threshold, geometry and progress as in
:class:`algorithms.surfaces.voxel_faces.VoxelSurfaceFilter`.
"""

from __future__ import annotations

from ...common.progress import report, scaled
from ..voxel_faces import VoxelSurfaceFilter
from .core import HybridSurface, TowerStrips, hybrid, tower_strips


class TowerFilter(VoxelSurfaceFilter):
    """VTK filter around :func:`tower_strips`: an image's visible voxel faces as triangle strips (``GetStrips``).

    Threshold and geometry as in :class:`algorithms.surfaces.voxel_faces.VoxelSurfaceFilter`.

    Examples
    --------
    >>> from algorithms.common.vtk_bridge import image_from_array, run_algorithm
    >>> f = TowerFilter()
    >>> f.SetInputDataObject(0, image_from_array(volume, spacing, origin))
    >>> f.SetThreshold(300.0)
    >>> polydata = run_algorithm(f)    # polydata.GetStrips() holds one cell per strip
    """

    @staticmethod
    def _extract(array, **options) -> TowerStrips:
        return tower_strips(array, **options)


class HybridFilter(VoxelSurfaceFilter):
    """VTK filter around :func:`hybrid`: short strips as triangles (``GetPolys``), long ones as strips.

    ``SetMaxStripVertices(L)`` (default 10, as in the source) sets the longest strip that is converted.
    Threshold and geometry as in :class:`algorithms.surfaces.voxel_faces.VoxelSurfaceFilter`.
    """

    def __init__(self) -> None:
        super().__init__()
        self._max_strip_vertices = 10

    def SetMaxStripVertices(self, value: int) -> None:  # noqa: N802 - VTK naming
        value = int(value)
        if value < 0:
            raise ValueError(f"max_strip_vertices must be >= 0, got {value}")
        if value != self._max_strip_vertices:
            self._max_strip_vertices = value
            self.Modified()

    def GetMaxStripVertices(self) -> int:  # noqa: N802
        return self._max_strip_vertices

    def _extract(self, array, *, progress, **options) -> HybridSurface:
        strips = tower_strips(array, progress=scaled(progress, 0.0, 0.9), **options)
        surface = hybrid(strips, max_strip_vertices=self._max_strip_vertices)
        report(progress, 1.0)
        return surface
