"""Refining a large OME-Zarr pyramid in the 3D views when the user zooms in (issue 19).

A volume opened at a coarse pyramid level (:func:`app.pyramid_view.load_pyramid_for_view`) is refined here: when the
camera has settled, :func:`app.pyramid_view.plan_region` says which level and region of the store the view needs;
the region is read off the GUI thread (:func:`app.pyramid_view.read_region`, a task with progress and Cancel in the
status bar) and given to the views that showed the volume, as a new item at its true place, in the same mode with
the same isovalue and transfer function. Zooming out shows the coarse volume again. All decisions are in ``app``;
this only listens to the camera and swaps the item the views show.
"""

from __future__ import annotations

from qtpy.QtCore import QObject, QTimer, Signal

from algorithms.common.camera import Camera
from app.pyramid_view import plan_region, pyramid_of, read_region
from app.scene import VolumeItem

from .tasks import Task

SETTLE_MILLISECONDS = 400  # the camera at rest this long -> decide what to read


class PyramidRefiner(QObject):
    """Watches the window's camera and shows the finest region of the pyramid the budget allows."""

    region_shown = Signal(object)  # the item now on show in the views (a region, or the coarse volume)

    def __init__(self, window) -> None:
        super().__init__(window)
        self.window = window
        self.chunked = None
        self.coarse_item = None
        self.plan = None
        self.shown_item = None
        self._task: Task | None = None
        self._closed = False
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(SETTLE_MILLISECONDS)
        self._timer.timeout.connect(self.refine)
        window.model.item_changed.connect(self._item_changed)
        window.camera_link.camera_moved.connect(self._camera_moved)

    def shutdown(self) -> None:
        """The window is closing: stop the timer, cancel a read and ignore every later signal (its views are shut
        down, so nothing may be shown in them any more)."""
        self._closed = True
        self._timer.stop()
        self._cancel()
        self.chunked = self.coarse_item = self.shown_item = None

    def _camera_moved(self, view) -> None:
        if self.chunked is not None and not self._closed:
            self._timer.start()

    def _item_changed(self, item) -> None:
        if self._closed:
            return
        self._cancel()
        self.plan = None
        base = self.window.model.base
        volume = getattr(item, "volume", None)
        self.chunked = pyramid_of(volume) if item is not None and item is base else None
        self.coarse_item = self.shown_item = item if self.chunked is not None else None

    def _cancel(self) -> None:
        if self._task is not None:
            self._task.cancel()
            self._task = None

    def refine(self) -> None:
        """Decide from the active view's camera; read a new region or go back to the coarse level if needed."""
        if self._closed or self.chunked is None or self.window.model.item is not self.coarse_item:
            return
        view = self.window.views[self.window.active_view]
        width, height = view.plotter.ren_win.GetSize()
        camera = Camera.from_vtk(view.renderer.GetActiveCamera())
        level = self.coarse_item.volume.metadata["pyramid"]["level"]
        plan = plan_region(self.chunked, camera, max(width, 1) / max(height, 1), coarse_level=level)
        if plan == self.plan or (self.plan is not None and self.plan.covers(plan)):
            return
        self._cancel()
        if plan is None:
            self._show(self.coarse_item, None)
            return
        name = self.coarse_item.name
        task = Task(f"Reading level {plan.level} of {name} in view", read_region, self.chunked, plan,
                    value_range=self.coarse_item.volume.value_range)
        task.finished.connect(lambda volume, task=task: self._read(task, plan, volume))
        task.failed.connect(lambda exc: self.window.statusBar().showMessage(f"{name}: {exc}", 15000))
        self._task = task
        self.window.tasks.start(task)

    def _read(self, task: Task, plan, volume) -> None:
        if self._closed or task is not self._task or self.window.model.item is not self.coarse_item:
            return  # a newer request, or another volume opened meanwhile
        self._task = None
        start, stop = plan.start, plan.stop
        name = (f"{self.coarse_item.name} (level {plan.level}, samples {start[2]}-{stop[2]} x {start[1]}-{stop[1]} x "
                f"{start[0]}-{stop[0]})")
        self._show(VolumeItem(name, volume=volume, metadata=dict(volume.metadata)), plan)

    def _show(self, item, plan) -> None:
        if self._closed:
            return
        for view in self.window.views[: self.window.model.view_count]:
            if view.item is not None and view.item in (self.coarse_item, self.shown_item):
                view.replace_item(item)
        self.plan, self.shown_item = plan, item
        self.region_shown.emit(item)
