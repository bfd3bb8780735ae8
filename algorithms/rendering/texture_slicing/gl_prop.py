"""The OpenGL path of texture slicing: the slices of a :class:`~.renderer.SlicingRenderer` as textured VTK polygons,
blended by the render window's framebuffer. See :mod:`algorithms.rendering.texture_slicing` for the method.
"""

from __future__ import annotations

import time

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkImageData

from ...common.camera import Camera
from ...common.progress import ProgressCallback, report
from ...common.vtk_bridge import polydata_from_arrays, vtk_matrix
from .renderer import SlicingRenderer
from .textures import layout_stats


class SliceStackProp:
    """The slices of a :class:`SlicingRenderer` as textured VTK polygons, composited by OpenGL.

    One ``vtkActor`` per slice (fan triangles with 2D texture coordinates and an RGBA ``unsigned char`` texture
    with premultiplied colour, linear filtering, clamped to its edge, no lighting), gathered in a ``vtkAssembly``
    in back-to-front order: VTK draws an assembly's parts in order and writes no depth for translucent geometry,
    and the texture's premultiplied flag makes VTK blend with ``(ONE, ONE_MINUS_SRC_ALPHA)``, i.e.
    ``C = C_front a + C_back (1 - a)``.

    Parameters
    ----------
    slicer : SlicingRenderer
        Supplies the slices (mode, count) and their textures; its ``precision`` does not matter here (the
        framebuffer decides).
    user_matrix : ndarray (4, 4), optional
        Placement of the volume frame in the scene (e.g. ``Volume.local_to_world``); identity by default.

    Raises
    ------
    ValueError
        If ``user_matrix`` is not a finite 4x4 matrix.
    TypeError
        If ``slicer`` is not a :class:`SlicingRenderer`.

    Examples
    --------
    >>> stack = SliceStackProp(slicer, user_matrix=volume.local_to_world)
    >>> stack.attach(scene.renderer)            # adds the assembly; order-independent translucency off
    >>> stack.update(volume_frame_camera, 512, 512)
    >>> scene.set_camera(world_camera); scene.render()
    """

    def __init__(self, slicer: SlicingRenderer, *, user_matrix=None) -> None:
        from vtkmodules.vtkRenderingCore import vtkAssembly
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 - the OpenGL mappers and textures must be registered

        if not isinstance(slicer, SlicingRenderer):
            raise TypeError(f"slicer must be a SlicingRenderer, got {type(slicer).__name__}")
        matrix = np.eye(4) if user_matrix is None else np.asarray(user_matrix, dtype=np.float64)
        if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
            raise ValueError(f"user_matrix must be a finite 4x4 matrix, got shape {matrix.shape}")
        self.slicer = slicer
        placement = vtk_matrix(matrix)
        self.prop = vtkAssembly()
        self.prop.SetUserMatrix(placement)
        self._actors: list = []
        self._shown = 0

    def attach(self, renderer) -> None:
        """Add the stack to a ``vtkRenderer`` and switch off what would reorder its blending.

        Order-independent translucency (VTK's default) averages translucent fragments with weights instead of
        applying the over operator in drawing order, and depth peeling is unnecessary for geometry already drawn
        back to front; both are turned off on ``renderer``.
        """
        renderer.SetUseOIT(False)
        renderer.SetUseDepthPeeling(False)
        renderer.AddActor(self.prop)

    def _actor(self, index: int):
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkTexture

        while len(self._actors) <= index:
            texture = vtkTexture()
            texture.InterpolateOn()
            texture.RepeatOff()
            texture.EdgeClampOn()
            texture.MipmapOff()
            texture.SetPremultipliedAlpha(True)
            mapper = vtkPolyDataMapper()
            mapper.ScalarVisibilityOff()
            actor = vtkActor()
            actor.SetMapper(mapper)
            actor.SetTexture(texture)
            actor.ForceTranslucentOn()
            properties = actor.GetProperty()
            properties.LightingOff()
            properties.SetColor(1.0, 1.0, 1.0)
            properties.SetOpacity(1.0)
            self._actors.append(actor)
        return self._actors[index]

    def update(self, camera: Camera, width: int, height: int, *, tools=None,
               progress: ProgressCallback = None) -> dict:
        """Rebuild the slices and textures for ``camera`` (volume frame) and an image of ``width`` x ``height``.

        Returns the numbers of :func:`layout_stats` plus ``seconds`` spent here (the textures are uploaded to
        OpenGL at the next render). The same as :meth:`compute` followed by :meth:`show`.
        """
        parts, stats = self.compute(camera, width, height, tools=tools, progress=progress)
        self.show(parts)
        return stats

    def compute(self, camera: Camera, width: int, height: int, *, tools=None, progress: ProgressCallback = None):
        """The slices and textures for ``camera`` as VTK data objects, without touching the actors, so it may run
        off the thread that renders; ``tools`` (a :class:`~algorithms.common.cutaway.ToolSet`, volume frame) cut
        the textures per texel. Returns ``(parts, stats)``; hand ``parts`` to :meth:`show` on that thread."""
        start = time.perf_counter()
        layout = self.slicer.layout(camera, width, height)
        _, triangles, triangle_slice = layout.polygons.fan_triangles()
        first_point = np.cumsum(layout.polygons.counts) - layout.polygons.counts
        total = max(int(layout.visible.sum()), 1)
        parts = []
        for done, (index, texture) in enumerate(self.slicer.iter_textures(layout, camera, size=(width, height),
                                                                              tools=tools)):
            points = layout.polygons.polygon(index)
            polydata = polydata_from_arrays(points, triangles[triangle_slice == index] - first_point[index])
            coordinates = numpy_support.numpy_to_vtk(
                np.ascontiguousarray(texture.texture_coordinates(points), dtype=np.float32), deep=True)
            coordinates.SetName("TextureCoordinates")
            polydata.GetPointData().SetTCoords(coordinates)
            texel_rows, texel_columns = texture.rgba.shape[:2]
            image = vtkImageData()
            image.SetDimensions(texel_columns, texel_rows, 1)
            scalars = numpy_support.numpy_to_vtk(
                np.clip(np.rint(texture.rgba * 255.0), 0, 255).astype(np.uint8).reshape(-1, 4), deep=True)
            scalars.SetName("rgba")
            image.GetPointData().SetScalars(scalars)
            parts.append((polydata, image))
            report(progress, (done + 1) / total)
        return parts, {"seconds": time.perf_counter() - start, **layout_stats(layout)}

    def show(self, parts: list) -> None:
        """Put slices made by :meth:`compute` on the actors, back to front (on the thread that renders)."""
        actors = []
        for done, (polydata, image) in enumerate(parts):
            actor = self._actor(done)
            actor.GetMapper().SetInputData(polydata)
            actor.GetTexture().SetInputData(image)
            actors.append(actor)
        self._replace_parts(actors)

    def _replace_parts(self, parts: list) -> None:
        """Show exactly ``parts``, in order (the assembly draws its parts in the order they were added)."""
        for actor in self._actors[: self._shown]:
            self.prop.RemovePart(actor)
        for actor in parts:
            self.prop.AddPart(actor)
        self._shown = len(parts)
        self.prop.Modified()

    @property
    def actors(self) -> list:
        """The actors currently shown, back to front."""
        return self._actors[: self._shown]
