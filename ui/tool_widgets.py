"""The cut-away tool of a 3D view as a VTK widget: a box (``vtkBoxWidget2``: move, rotate, scale by its faces),
a sphere (``vtkSphereWidget2``) or a plane (``vtkImplicitPlaneWidget2``), the selected tool of the shared
:class:`app.cutaways.Cutaways` (source 002, section 2.5: a selection volume placed by an affine transform).

Every linked 3D view has one :class:`ToolWidget`; all show the same tool. Dragging calls ``on_moved(tool, moving)``
with the tool the widget now describes (``moving`` True during the drag, False at release), and the window
replaces the tool in the selection, which the views' pipelines then evaluate per sample. Computes nothing itself:
the tool's geometry comes from :mod:`algorithms.fields.cutaway_tools`. Cylinder and grid tools have no widget (they are
moved from the command line or the tool list).
"""

from __future__ import annotations

import numpy as np


def _matrix_of(transform) -> np.ndarray:
    from vtkmodules.vtkCommonMath import vtkMatrix4x4

    matrix = vtkMatrix4x4()
    transform.GetMatrix(matrix)
    return np.array([[matrix.GetElement(r, c) for c in range(4)] for r in range(4)])


class ToolWidget:
    """The widget of the selected tool in one :class:`ui.render_view.RenderView`."""

    def __init__(self, view, on_moved) -> None:
        from vtkmodules.vtkInteractionWidgets import (
            vtkBoxRepresentation,
            vtkBoxWidget2,
            vtkImplicitPlaneRepresentation,
            vtkImplicitPlaneWidget2,
            vtkSphereRepresentation,
            vtkSphereWidget2,
        )

        self.view = view
        self.on_moved = on_moved
        self.tool = None
        self.shape = None
        self._base_size = np.ones(3)
        box = vtkBoxRepresentation()
        box.SetPlaceFactor(1.0)
        box.GetOutlineProperty().SetColor(1.0, 0.8, 0.2)
        sphere = vtkSphereRepresentation()
        sphere.SetRepresentationToWireframe()
        sphere.HandleVisibilityOff()
        plane = vtkImplicitPlaneRepresentation()
        plane.SetPlaceFactor(1.0)
        plane.OutlineTranslationOff()
        plane.GetPlaneProperty().SetOpacity(0.15)
        self.representations = {"box": box, "sphere": sphere, "plane": plane}
        self.widgets = {"box": vtkBoxWidget2(), "sphere": vtkSphereWidget2(), "plane": vtkImplicitPlaneWidget2()}
        for shape, widget in self.widgets.items():
            widget.SetRepresentation(self.representations[shape])
            widget.SetInteractor(view.plotter.iren.interactor)
            widget.SetCurrentRenderer(view.renderer)
            widget.AddObserver("InteractionEvent", lambda *_: self._changed(moving=True))
            widget.AddObserver("EndInteractionEvent", lambda *_: self._changed(moving=False))

    @property
    def enabled(self) -> bool:
        return self.shape is not None

    def show_tool(self, tool) -> None:
        """Show ``tool`` (or nothing for None, a hidden tool or a shape without a widget); does not call back."""
        shape = tool.shape if tool is not None and tool.visible and tool.shape in self.widgets else None
        for name, widget in self.widgets.items():
            if name != shape and widget.GetEnabled():
                widget.SetEnabled(0)
        self.tool, self.shape = tool, shape
        if shape is None:
            return
        representation = self.representations[shape]
        if shape == "box":
            from vtkmodules.vtkCommonTransforms import vtkTransform

            from algorithms.common.vtk_bridge import vtk_matrix

            half = np.asarray(tool.size) / 2
            self._base_size = np.asarray(tool.size, dtype=np.float64)
            representation.PlaceWidget([float(v) for pair in zip(-half, half) for v in pair])
            transform = vtkTransform()
            transform.SetMatrix(vtk_matrix(tool.matrix))
            representation.SetTransform(transform)
        elif shape == "sphere":
            representation.SetCenter(*map(float, tool.centre))
            representation.SetRadius(float(tool.size[0]))
        else:
            bounds = self.view.pipeline.content.bounds() if hasattr(self.view.pipeline.content, "bounds") else None
            centre = np.asarray(tool.centre)
            if bounds is None:
                bounds = [float(c + d) for c in centre for d in (-100.0, 100.0)]
            representation.PlaceWidget(bounds)
            representation.SetOrigin(*map(float, centre))
            representation.SetNormal(*map(float, tool.matrix[:3, 2]))
        self.widgets[shape].SetEnabled(1)

    def current_tool(self):
        """The tool as the widget now places it (LPS mm)."""
        tool, shape = self.tool, self.shape
        if tool is None or shape is None:
            return tool
        representation = self.representations[shape]
        if shape == "box":
            from vtkmodules.vtkCommonTransforms import vtkTransform

            transform = vtkTransform()
            representation.GetTransform(transform)
            matrix = _matrix_of(transform)
            scales = np.linalg.norm(matrix[:3, :3], axis=0)
            rigid = np.eye(4)
            rigid[:3, :3] = matrix[:3, :3] / np.where(scales > 0, scales, 1.0)
            rigid[:3, 3] = matrix[:3, 3]
            size = tuple(float(v) for v in self._base_size * scales)
            from dataclasses import replace

            return replace(tool, matrix=rigid, size=size)
        if shape == "sphere":
            return tool.moved(centre=representation.GetCenter(), size=(float(representation.GetRadius()),))
        from algorithms.fields.cutaway_tools import plane_tool

        moved = plane_tool(representation.GetOrigin(), representation.GetNormal(), mode=tool.mode)
        return tool.with_matrix(moved.matrix)

    def _changed(self, *, moving: bool) -> None:
        tool = self.current_tool()
        if tool is not None:
            self.tool = tool
            self.on_moved(self, tool, moving)
