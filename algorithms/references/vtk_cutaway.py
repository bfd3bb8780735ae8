"""VTK's own way of cutting a volume with a shape: ``vtkImplicitFunctionToImageStencil`` feeding ``vtkImageStencil``,
the reference our per-sample tools (:mod:`algorithms.common.cutaway`, source 002 section 2.5) are checked against
voxel for voxel; and the masks VTK's volume mappers take.

The shapes are VTK implicit functions placed by a ``vtkTransform`` (VTK applies an implicit function's transform to
the point before evaluating it, so it is given the tool's inverse: frame -> tool): ``vtkSphere``, ``vtkBox`` (bounds
+-half sizes), a capped cylinder (``vtkCylinder`` along z, intersected with two ``vtkPlane`` caps by
``vtkImplicitBoolean``) and a ``vtkPlane``. ``vtkImplicitFunctionToImageStencil`` marks the voxels where the function
is below its threshold (0); ``vtkImageStencil`` then keeps them (or, reversed, everything else).

What VTK cannot do that ours does: the stencil is a rewrite of the voxels (a new image for every move of the tool);
``vtkGPUVolumeRayCastMapper`` takes a mask only on the volume's own grid (``SetMaskInput``, no transform of its
own, so a moved tool means a new mask), and ``vtkFixedPointVolumeRayCastMapper`` takes no mask at all (only clipping
planes, which keep an intersection of half-spaces and cannot remove an octant).

Arrays are ``(nz, ny, nx)``; images are in the frame of the tools' matrices (index times spacing, mm, origin 0).
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import (
    vtkBox,
    vtkCylinder,
    vtkImageData,
    vtkImplicitBoolean,
    vtkPlane,
    vtkSphere,
)
from vtkmodules.vtkCommonTransforms import vtkTransform
from vtkmodules.vtkImagingStencil import vtkImageStencil, vtkImplicitFunctionToImageStencil

from ..common.vtk_bridge import run_algorithm, vtk_matrix


def implicit_function(shape: str, size, frame_to_tool):
    """A VTK implicit function (negative inside) of a ``sphere`` (radius), ``box`` (full sizes), ``cylinder`` (radius,
    height, axis z) or ``plane`` (the half-space its +z side points into) whose points are first mapped by the 4x4
    ``frame_to_tool``."""
    transform = vtkTransform()
    transform.SetMatrix(vtk_matrix(np.asarray(frame_to_tool, dtype=np.float64)))
    if shape == "sphere":
        function = vtkSphere()
        function.SetRadius(float(size[0]))
        function.SetCenter(0.0, 0.0, 0.0)
    elif shape == "box":
        hx, hy, hz = (float(v) / 2 for v in size)
        function = vtkBox()
        function.SetBounds(-hx, hx, -hy, hy, -hz, hz)
    elif shape == "cylinder":
        radius, height = float(size[0]), float(size[1])
        tube = vtkCylinder()  # VTK's cylinder runs along y: turn it onto z
        tube.SetRadius(radius)
        tube.SetAxis(0.0, 0.0, 1.0)
        top, bottom = vtkPlane(), vtkPlane()
        top.SetOrigin(0.0, 0.0, height / 2)
        top.SetNormal(0.0, 0.0, 1.0)
        bottom.SetOrigin(0.0, 0.0, -height / 2)
        bottom.SetNormal(0.0, 0.0, -1.0)
        function = vtkImplicitBoolean()
        function.SetOperationTypeToIntersection()
        for part in (tube, top, bottom):
            function.AddFunction(part)
    elif shape == "plane":
        function = vtkPlane()
        function.SetOrigin(0.0, 0.0, 0.0)
        function.SetNormal(0.0, 0.0, -1.0)  # negative on the +z side: inside is where the normal points
    else:
        raise ValueError(f"VTK's stencil reference covers sphere, box, cylinder and plane tools, not {shape!r}")
    function.SetTransform(transform)
    return function


def stencil_mask(shape_zyx, spacing, functions) -> np.ndarray:
    """Boolean ``(nz, ny, nx)``: the voxels (centres at ``(i sx, j sy, k sz)``) inside any of ``functions``, found by
    ``vtkImplicitFunctionToImageStencil`` + ``vtkImageStencil`` on an image of ones (background 0)."""
    nz, ny, nx = (int(n) for n in shape_zyx)
    ones = vtkImageData()
    ones.SetDimensions(nx, ny, nz)
    ones.SetSpacing(*(float(s) for s in spacing))
    ones.SetOrigin(0.0, 0.0, 0.0)
    scalars = numpy_support.numpy_to_vtk(np.ones(nx * ny * nz, dtype=np.uint8), deep=True)
    ones.GetPointData().SetScalars(scalars)
    inside = np.zeros((nz, ny, nx), dtype=bool)
    for function in functions:
        to_stencil = vtkImplicitFunctionToImageStencil()
        to_stencil.SetInput(function)
        to_stencil.SetOutputOrigin(0.0, 0.0, 0.0)
        to_stencil.SetOutputSpacing(*(float(s) for s in spacing))
        to_stencil.SetOutputWholeExtent(0, nx - 1, 0, ny - 1, 0, nz - 1)
        to_stencil.SetThreshold(0.0)
        stencil = vtkImageStencil()
        stencil.SetInputData(ones)
        stencil.SetStencilConnection(to_stencil.GetOutputPort())
        stencil.ReverseStencilOff()
        stencil.SetBackgroundValue(0.0)
        output = run_algorithm(stencil)
        values = numpy_support.vtk_to_numpy(output.GetPointData().GetScalars()).reshape(nz, ny, nx)
        inside |= values != 0
    return inside


def stencilled_image(image, functions, *, background: float, reverse: bool = True):
    """``image`` (``vtkImageData``, origin 0) with the voxels inside ``functions`` replaced by ``background``
    (``reverse=True``, a cut-away) or with everything else replaced (``reverse=False``, a region of interest): VTK's
    data-rewriting cut."""
    output = image
    for function in functions:
        to_stencil = vtkImplicitFunctionToImageStencil()
        to_stencil.SetInput(function)
        to_stencil.SetInformationInput(image)
        stencil = vtkImageStencil()
        stencil.SetInputData(output)
        stencil.SetStencilConnection(to_stencil.GetOutputPort())
        stencil.SetReverseStencil(bool(reverse))
        stencil.SetBackgroundValue(float(background))
        output = run_algorithm(stencil)
    return output


def mask_image(kept, spacing):
    """A ``vtkImageData`` mask for ``vtkGPUVolumeRayCastMapper.SetMaskInput`` (binary mask type): 255 where the
    boolean ``kept`` ``(nz, ny, nx)`` is True, 0 where the mapper must skip the voxel."""
    nz, ny, nx = kept.shape
    image = vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetSpacing(*(float(s) for s in spacing))
    image.SetOrigin(0.0, 0.0, 0.0)
    values = numpy_support.numpy_to_vtk(np.where(kept.reshape(-1), 255, 0).astype(np.uint8), deep=True)
    values.SetName("mask")
    image.GetPointData().SetScalars(values)
    return image


__all__ = ["implicit_function", "mask_image", "stencil_mask", "stencilled_image"]
