"""Linked cameras: all views share one ``vtkCamera`` while linked, and each gets its own copy when unlinked.

Sharing the camera object (rather than copying parameters after the fact) keeps every view exactly in step,
including during a drag. Any change of the shared camera asks the other views to redraw, coalesced per event loop
turn so a drag does not queue a backlog of renders.
"""

from __future__ import annotations

from typing import Callable

from qtpy.QtCore import QObject, QTimer, Signal
from vtkmodules.vtkRenderingCore import vtkCamera


def _pose(camera: vtkCamera) -> tuple:
    return (camera.GetPosition(), camera.GetFocalPoint(), camera.GetViewUp(), camera.GetViewAngle(),
            camera.GetParallelProjection(), camera.GetParallelScale())


class CameraLink(QObject):
    """Owns the shared camera and tells views when it moved."""

    camera_moved = Signal(object)  # the view (or None) whose camera moved

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.shared = vtkCamera()
        self.linked = True
        self._views: list = []
        self._observers: dict[int, tuple[vtkCamera, int]] = {}
        self._pending: set = set()
        self._flush = QTimer(self)
        self._flush.setSingleShot(True)
        self._flush.setInterval(0)
        self._flush.timeout.connect(self._emit_pending)
        self._watch(None, self.shared)

    def attach(self, view) -> None:
        """Give ``view`` (anything with a ``renderer``) the shared camera, or its own copy when unlinked."""
        if view not in self._views:
            self._views.append(view)
        camera = self.shared if self.linked else self._copy(self.shared)
        view.renderer.SetActiveCamera(camera)
        if not self.linked:
            self._watch(view, camera)

    def detach(self, view) -> None:
        if view in self._views:
            self._views.remove(view)
        self._unwatch(view)

    def set_linked(self, linked: bool) -> None:
        if linked == self.linked:
            return
        self.linked = linked
        if linked:
            # Everyone follows the shared camera again (it keeps the pose of the first view).
            first = self._views[0].renderer.GetActiveCamera() if self._views else self.shared
            self.shared.DeepCopy(first)
            for view in self._views:
                self._unwatch(view)
                view.renderer.SetActiveCamera(self.shared)
        else:
            for view in self._views:
                camera = self._copy(self.shared)
                view.renderer.SetActiveCamera(camera)
                self._watch(view, camera)
        self._moved(None)

    def camera_of(self, view) -> vtkCamera:
        return view.renderer.GetActiveCamera()

    def views_following(self, view) -> list:
        """The views that show the camera ``view`` uses (all of them when linked)."""
        return list(self._views) if self.linked else [view]

    # -- internals --------------------------------------------------------------------------------------------
    @staticmethod
    def _copy(camera: vtkCamera) -> vtkCamera:
        copy = vtkCamera()
        copy.DeepCopy(camera)
        return copy

    def _watch(self, view, camera: vtkCamera) -> None:
        self._unwatch(view)
        last_pose = [_pose(camera)]

        def modified(*_):
            # Renderers reset the clipping range before every frame, which also modifies the camera; only a new
            # pose (position, focal point, view up, angle, projection) counts as a move.
            pose = _pose(camera)
            if pose != last_pose[0]:
                last_pose[0] = pose
                self._moved(view)

        tag = camera.AddObserver("ModifiedEvent", modified)
        self._observers[id(view)] = (camera, tag)

    def _unwatch(self, view) -> None:
        entry = self._observers.pop(id(view), None)
        if entry is not None:
            entry[0].RemoveObserver(entry[1])

    def _moved(self, view) -> None:
        self._pending.add(view)
        if not self._flush.isActive():
            self._flush.start()

    @property
    def pending(self) -> bool:
        """A camera move has not been announced to the views yet."""
        return bool(self._pending)

    def flush(self) -> None:
        """Announce pending camera moves now instead of on the next turn of the event loop."""
        self._flush.stop()
        self._emit_pending()

    def _emit_pending(self) -> None:
        pending, self._pending = self._pending, set()
        for view in pending:
            self.camera_moved.emit(view)

    def each_view(self, action: Callable) -> None:
        for view in list(self._views):
            action(view)
