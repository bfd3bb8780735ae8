"""Our voxelisation against VTK's ``vtkPolyDataToImageStencil`` + ``vtkImageStencilToImage`` on the same grids:
closed meshes made in code and the real closed meshes, at 64^3 and 256^3, an anisotropic 0.5 x 0.5 x 2 mm grid and
a rotated one."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.fields.voxelise import voxelise
from algorithms.references.vtk_fields import vtk_stencil_mask

from ._voxelise_shapes import real_mesh, rotation, sphere, torus

#: Longest side of the real meshes after scaling to patient size (their files are in model units).
REAL_SIZE_MM = 150.0


def _mesh(name):
    if name == "sphere":
        return sphere(40.0, around=360, across=180)
    if name == "torus":
        return torus(45.0, 15.0, around=360, across=180)
    points, triangles, _ = real_mesh(f"{name}.obj.gz")
    low, high = points.min(axis=0), points.max(axis=0)
    return (points - (low + high) / 2) * (REAL_SIZE_MM / (high - low).max()), triangles


def _grid(points, kind):
    low, high = points.min(axis=0), points.max(axis=0)
    bounds = np.ravel(np.column_stack([low, high]))
    if kind in ("64", "256"):
        return Grid.around(bounds, voxels=int(kind))
    if kind == "anisotropic":
        return Grid.around(bounds, spacing=(0.5, 0.5, 2.0))
    # rotated and anisotropic, around the mesh in the grid's own frame
    direction = rotation((1.0, 2.0, 3.0), 37.0)
    spacing = np.array([0.7, 0.9, 1.3])
    local = points @ direction
    first = np.floor(local.min(axis=0) / spacing) - 2
    last = np.ceil(local.max(axis=0) / spacing) + 2
    origin = direction @ (first * spacing)
    return Grid(tuple(int(n) for n in last - first + 1), tuple(spacing), tuple(origin), tuple(direction.ravel()))


@pytest.mark.parametrize("kind", ["64", "256", "anisotropic", "rotated"])
@pytest.mark.parametrize("name", ["sphere", "torus", "spot", "cow", "fandisk"])
def test_agrees_with_vtk_stencil(name, kind):
    points, triangles = _mesh(name)
    grid = _grid(points, kind)
    ours = voxelise(points, triangles, grid)
    theirs = vtk_stencil_mask((points, triangles), grid)
    both = np.count_nonzero(ours & theirs)
    either = np.count_nonzero(ours | theirs)
    differing = int(np.count_nonzero(ours != theirs))
    assert both > 1000
    assert both / either >= 0.99999, f"IoU {both / either:.7f}, {differing} voxels differ of {either}"


def test_vtk_stencil_tolerance_widens_its_mask():
    """VTK's default tolerance (1e-3 voxel) counts centres just outside; our comparison runs it with 0."""
    points, triangles = sphere(40.0, around=360, across=180)
    grid = Grid.around((-40, 40, -40, 40, -40, 40), voxels=96)
    exact = vtk_stencil_mask((points, triangles), grid)
    wide = vtk_stencil_mask((points, triangles), grid, tolerance=0.25)
    assert np.all(wide >= exact) and wide.sum() > exact.sum()
