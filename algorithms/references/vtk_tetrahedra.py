"""VTK's tetrahedralisations, the references of isosurface stuffing, run the way we run our own filters.

- :func:`vtk_delaunay_tetrahedra`: ``vtkDelaunay3D`` on the points of the isosurface (``vtkFlyingEdges3D``). Delaunay
  fills the convex hull of the points; the tetrahedra outside the shape are removed afterwards: a tetrahedron is
  kept when the volume's trilinear interpolant at its centroid is inside (``value >= iso``, or ``<=`` for fields
  negative inside), the same field the isosurface is a level set of. Both counts are reported.
- :func:`vtk_clip_tetrahedra`: ``vtkClipVolume`` on the image at the isovalue with ``Mixed3DCellGeneration`` off,
  so every cell of the output is a tetrahedron (the voxels cut by the surface and the voxels inside, each split
  into tetrahedra).
- :func:`vtk_min_dihedral`: ``vtkMeshQuality`` with ``SetTetQualityMeasureToMinAngle``: the smallest dihedral angle
  of every tetrahedron (degrees), VTK's own measure of what :mod:`algorithms.compare.tet_quality` computes.

Volumes are ``(nz, ny, nx)`` arrays with spacing and origin ``(x, y, z)`` mm; meshes come back as
:class:`~algorithms.common.mesh.TetMesh` in the volume frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from vtkmodules.util import numpy_support

from ..common.mesh import TetMesh
from ..common.progress import ProgressCallback, scaled
from ..common.vtk_bridge import image_from_array, run_algorithm

__all__ = ["VTKTetrahedra", "unstructured_tetrahedra", "vtk_clip_tetrahedra", "vtk_delaunay_tetrahedra",
           "vtk_min_dihedral"]


@dataclass
class VTKTetrahedra:
    """A VTK tetrahedralisation as a :class:`TetMesh` with its timings (s) and counts."""

    mesh: TetMesh
    seconds: dict[str, float] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)


def unstructured_tetrahedra(grid) -> TetMesh:
    """The tetrahedra of a ``vtkUnstructuredGrid`` (other cell types are dropped) as a :class:`TetMesh`."""
    return TetMesh.from_unstructured_grid(grid)


def _inside_at(array, iso, spacing, origin, positions, above: bool) -> np.ndarray:
    from scipy.ndimage import map_coordinates

    index = (np.asarray(positions) - np.asarray(origin)) / np.asarray(spacing)
    values = map_coordinates(array.astype(np.float32, copy=False), index[:, ::-1].T, order=1, mode="nearest")
    return values >= iso if above else values <= iso


def vtk_delaunay_tetrahedra(volume, iso: float, *, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0),
                            inside: str = "above", progress: ProgressCallback = None) -> VTKTetrahedra:
    """``vtkDelaunay3D`` on the isosurface's points, tetrahedra outside the shape removed (see the module notes)."""
    from vtkmodules.vtkFiltersCore import vtkDelaunay3D, vtkFlyingEdges3D

    array = np.asarray(volume)
    image = image_from_array(array, spacing, origin)
    start = time.perf_counter()
    contour = vtkFlyingEdges3D()
    contour.SetInputData(image)
    contour.SetValue(0, float(iso))
    contour.ComputeNormalsOff()
    contour.ComputeScalarsOff()
    surface = run_algorithm(contour, scaled(progress, 0.0, 0.1))
    seconds = {"surface": time.perf_counter() - start}
    tick = time.perf_counter()
    delaunay = vtkDelaunay3D()
    delaunay.SetInputData(surface)
    grid = run_algorithm(delaunay, scaled(progress, 0.1, 0.9))
    hull = unstructured_tetrahedra(grid)
    seconds["delaunay"] = time.perf_counter() - tick
    tick = time.perf_counter()
    centroids = hull.points[hull.tetrahedra].mean(axis=1) if hull.n_tetrahedra else np.empty((0, 3))
    keep = _inside_at(array, iso, spacing, origin, centroids, inside == "above") if len(centroids) else \
        np.zeros(0, dtype=bool)
    mesh = TetMesh(hull.points, hull.tetrahedra[keep])
    seconds["remove_outside"] = time.perf_counter() - tick
    seconds["total"] = time.perf_counter() - start
    stats = {"hull_tetrahedra": hull.n_tetrahedra, "tetrahedra": mesh.n_tetrahedra, "points": mesh.n_points,
             "surface_points": int(surface.GetNumberOfPoints()),
             "removed": "tetrahedra whose centroid's trilinear value is outside the isovalue"}
    return VTKTetrahedra(mesh, seconds, stats)


def vtk_clip_tetrahedra(volume, iso: float, *, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0),
                        inside: str = "above", progress: ProgressCallback = None) -> VTKTetrahedra:
    """``vtkClipVolume`` of the image at ``iso``, tetrahedra only (``Mixed3DCellGeneration`` off)."""
    from vtkmodules.vtkFiltersGeneral import vtkClipVolume

    image = image_from_array(np.asarray(volume), spacing, origin)
    start = time.perf_counter()
    clip = vtkClipVolume()
    clip.SetInputData(image)
    clip.SetValue(float(iso))
    clip.Mixed3DCellGenerationOff()
    clip.SetInsideOut(inside != "above")  # default keeps values above the value
    grid = run_algorithm(clip, progress)
    mesh = unstructured_tetrahedra(grid)
    seconds = {"total": time.perf_counter() - start}
    return VTKTetrahedra(mesh, seconds, {"tetrahedra": mesh.n_tetrahedra, "points": mesh.n_points})


def vtk_min_dihedral(mesh: TetMesh) -> np.ndarray:
    """The smallest dihedral angle (degrees) of every tetrahedron by ``vtkMeshQuality`` (``TetMinAngle``)."""
    from vtkmodules.vtkFiltersVerdict import vtkMeshQuality

    quality = vtkMeshQuality()
    quality.SetInputData(mesh.to_unstructured_grid())
    quality.SetTetQualityMeasureToMinAngle()
    output = run_algorithm(quality)
    return numpy_support.vtk_to_numpy(output.GetCellData().GetArray("Quality")).astype(np.float64)
