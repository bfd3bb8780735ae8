"""The clip-plane widget of a 3D view: a ``vtkImplicitPlaneWidget2`` the user drags to cut a tetrahedral mesh open.

Shown only while the view's mode says it clips (``Capabilities.clip_plane``). While the plane is dragged the view's
content moves its plane at once (``set_clip_plane``: no new mesh, only a new cut); when the drag ends the plane is
written back as the mode's ``clip_origin`` and ``clip_normal`` options through the view's ``options_chosen`` signal,
the same way the options panel writes them, so the command line can reproduce the view
(``voxelscope render --mode stuffing --clip-origin "x y z" --clip-normal "x y z"``). Computes nothing itself.
"""

from __future__ import annotations

import numpy as np


def format_vector(values) -> str:
    """``"x y z"`` with four decimals (the form of the ``clip_origin``/``clip_normal`` options)."""
    return " ".join(f"{float(v):.4f}" for v in values)


class ClipPlaneWidget:
    """The plane widget of one :class:`ui.render_view.RenderView`."""

    def __init__(self, view) -> None:
        from vtkmodules.vtkInteractionWidgets import vtkImplicitPlaneRepresentation, vtkImplicitPlaneWidget2

        self.view = view
        self.representation = vtkImplicitPlaneRepresentation()
        self.representation.SetPlaceFactor(1.0)
        self.representation.OutlineTranslationOff()
        self.representation.ScaleEnabledOff()
        self.representation.SetTubing(False)
        self.representation.GetPlaneProperty().SetOpacity(0.15)
        self.widget = vtkImplicitPlaneWidget2()
        self.widget.SetRepresentation(self.representation)
        self.widget.SetInteractor(view.plotter.iren.interactor)
        self.widget.SetCurrentRenderer(view.renderer)
        self.widget.AddObserver("InteractionEvent", self._dragged)
        self.widget.AddObserver("EndInteractionEvent", self._released)
        self.enabled = False
        view.pipeline.ready.connect(self._content_ready)

    # -- what the view calls -------------------------------------------------------------------------------------
    def mode_changed(self) -> None:
        """The view shows another mode: hide the widget unless the mode clips (placed again when it is ready)."""
        if not self._clips():
            self._set_enabled(False)

    def plane(self) -> tuple[np.ndarray, np.ndarray]:
        """The widget's plane: ``(origin, normal)`` in LPS mm."""
        return np.array(self.representation.GetOrigin()), np.array(self.representation.GetNormal())

    def set_plane(self, origin, normal, *, write_back: bool = True) -> None:
        """Move the plane (what a drag does, for scripts and tests): the content clips at once and, with
        ``write_back``, the plane becomes the mode's options."""
        self.representation.SetOrigin(*map(float, origin))
        self.representation.SetNormal(*map(float, normal))
        self._dragged()
        if write_back:
            self._released()

    # -- internals -------------------------------------------------------------------------------------------------
    def _clips(self) -> bool:
        mode = self.view.pipeline.mode
        return bool(mode is not None and mode.capabilities.clip_plane)

    def _set_enabled(self, on: bool) -> None:
        if on != self.enabled:
            self.widget.SetEnabled(1 if on else 0)
            self.enabled = on

    def _content_ready(self) -> None:
        content = self.view.pipeline.content
        if not self._clips() or content is None or not hasattr(content, "bounds") or content.bounds() is None:
            self._set_enabled(False)
            return
        from app.modes.tetrahedra import clip_plane

        bounds = content.bounds()
        self.representation.PlaceWidget(bounds)
        plane = clip_plane(self.view.pipeline.options, bounds)
        if plane is not None:
            self.representation.SetOrigin(*plane[0])
            self.representation.SetNormal(*plane[1])
        self._set_enabled(bool(self.view.pipeline.options.get("clip", True)))

    def _dragged(self, *args) -> None:
        content = self.view.pipeline.content
        if content is not None and hasattr(content, "set_clip_plane"):
            origin, normal = self.plane()
            content.set_clip_plane(origin, normal)
            self.view.render()

    def _released(self, *args) -> None:
        origin, normal = self.plane()
        self.view.options_chosen.emit(self.view.index, {"clip_origin": format_vector(origin),
                                                        "clip_normal": format_vector(normal)})
