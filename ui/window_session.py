"""The workbench window's sessions: File > Save session writes the model's state (:mod:`app.session`) plus the
window's own (dock arrangement, geometry, splitter, the view shown alone, cameras); File > Open session (and
``voxelscope gui --session FILE``) loads the data in workers, then restores everything in that order. A mixin of
:class:`ui.main_window.MainWindow`."""

from __future__ import annotations

from pathlib import Path

from qtpy.QtCore import QByteArray
from qtpy.QtWidgets import QFileDialog

from algorithms.common.camera import Camera
from app.session import (apply_model_state, camera_from_dict, load_item, read_session, save_session, session_snapshot,
                         write_session_files)

from .tasks import Task

SESSION_FILTER = "Voxelscope session (*.voxelscope.json *.json)"


class SessionActions:
    # -- saving ---------------------------------------------------------------------------------------------------
    def _cameras(self) -> list:
        views = self.views[: self.model.view_count] if not self.model.cameras_linked else self.views[:1]
        return [Camera.from_vtk(view.renderer.GetActiveCamera()) for view in views]

    def window_state(self) -> dict:
        """The window's own part of a session (``"ui"``): docks, geometry, splitter, zoom, the tool in use."""
        enlarged = None
        if self.enlarged is not None:
            enlarged = (["slice", self.enlarged.plane] if self.enlarged in self.slice_views.values()
                        else ["view", self.enlarged.index])
        return {
            "geometry": bytes(self.saveGeometry().toBase64()).decode("ascii"),
            "docks": bytes(self.saveState().toBase64()).decode("ascii"),
            "splitter": list(self.splitter.sizes()),
            "slices_shown": self.slices_action.isChecked(),
            "enlarged": enlarged,
            "active_view": self.active_view,
            "parallel_projection": self.parallel_action.isChecked(),
            "tool": self.tool,
            "current_cutaway": self.current_tool,
            "zoom": {plane: [view.zoom, list(view.centre_st) if view.centre_st else None]
                     for plane, view in self.slice_views.items()},
        }

    def save_session(self, path, *, overwrite: bool = False) -> Path:
        """Write the session now (the items made in the session too; see :func:`app.session.save_session`)."""
        return save_session(path, self.model, cameras=self._cameras(), window=self.window_state(),
                            overwrite=overwrite)

    def save_session_dialog(self) -> None:
        if self.model.base is None:
            self._report_error("Open a volume before saving a session.", "Nothing to save")
            return
        path, _ = QFileDialog.getSaveFileName(self, "Save session", self._last_folder(), SESSION_FILTER)
        if not path:
            return
        path = Path(path) if path.lower().endswith(".json") else Path(path + ".voxelscope.json")
        # The state is taken now, on this thread; the files (fields can be large) are written in a worker.
        state, items = session_snapshot(self.model, cameras=self._cameras(), window=self.window_state())
        task = Task(f"Saving the session {path.name}", write_session_files, path, state, items,
                    overwrite=path.exists())  # the dialog asked before replacing
        task.finished.connect(lambda written: self.statusBar().showMessage(f"Saved the session {written}", 15000))
        task.failed.connect(lambda exc: self._report_error(f"Could not save the session {path}:\n\n{exc}"))
        self.tasks.start(task)

    # -- opening -------------------------------------------------------------------------------------------------
    def open_session_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open session", self._last_folder(), SESSION_FILTER)
        if path:
            self.open_session(path)

    def open_session(self, path) -> bool:
        """Open a session file: its volume, then its labels and meshes, then its state. ``session_opened(path)``
        when everything is restored; a clear message (and ``load_failed``) when the file cannot be used."""
        try:
            state = read_session(path)
        except ValueError as exc:
            self.load_failed.emit(str(exc))
            self._report_error(str(exc), "Could not open the session")
            return False
        data = state["data"]
        self._session = {"path": str(path), "state": state, "labels": list(data.get("labels", [])),
                         "meshes": [mesh for mesh in data.get("meshes", []) if Path(mesh).exists()],
                         "items": list(data.get("items", []))}
        self.volume_loaded.connect(self._session_step)
        self.load_failed.connect(self._session_failed)
        volume = data["volume"]
        self.open_path(volume["path"], series_uid=volume.get("series_uid"), labels=bool(volume.get("labels")))
        return True

    def _session_failed(self, message: str) -> None:
        self._end_session_loading()

    def _session_failed_with(self, message: str) -> None:
        self._end_session_loading()
        self.load_failed.emit(message)
        self._report_error(message, "Could not open the session")

    def _session_item_loaded(self, item) -> None:
        self.model.scene.add(item)
        self._session_step(None)

    def _end_session_loading(self) -> None:
        for signal, slot in ((self.volume_loaded, self._session_step), (self.load_failed, self._session_failed)):
            try:
                signal.disconnect(slot)
            except (RuntimeError, TypeError):
                pass
        session, self._session = getattr(self, "_session", None), None
        return session

    def _session_step(self, _data) -> None:
        session = getattr(self, "_session", None)
        if session is None:
            return
        if session["labels"]:  # one at a time: each load announces itself with volume_loaded
            entry = session["labels"].pop(0)
            tables = entry.get("color_tables") or []
            self.open_labels(entry["path"], color_table=tables[0] if len(tables) == 1 else None)
            return
        if session["meshes"]:
            self.open_path(session["meshes"].pop(0))
            return
        if session["items"]:  # what was made in the session, read from the session's own folder
            entry = session["items"].pop(0)
            task = Task(f"Reading {entry.get('name', 'an item')} of the session", load_item, session["path"], entry)
            task.finished.connect(self._session_item_loaded)
            task.failed.connect(lambda exc: self._session_failed_with(f"Could not restore the session's item "
                                                                      f"{entry.get('name')}:\n\n{exc}"))
            self.tasks.start(task)
            return
        session = self._end_session_loading()
        self._restore_session(session["state"])
        self.statusBar().showMessage(f"Opened the session {session['path']}", 15000)
        self.session_opened.emit(session["path"])

    def _restore_session(self, state: dict) -> None:
        window = state.get("ui", {})
        if window.get("geometry"):
            self.restoreGeometry(QByteArray.fromBase64(window["geometry"].encode("ascii")))
        if window.get("docks"):
            self.restoreState(QByteArray.fromBase64(window["docks"].encode("ascii")))
        count = len((state.get("cutaways") or {}).get("tools", []))
        self.current_tool = min(int(window.get("current_cutaway", 0)), count - 1)
        apply_model_state(self.model, state)
        self.parallel_action.setChecked(bool(window.get("parallel_projection", False)))
        self.slices_action.setChecked(bool(window.get("slices_shown", True)))
        self.slice_column.setVisible(self.slices_action.isChecked())
        if window.get("splitter"):
            self.splitter.setSizes([int(s) for s in window["splitter"]])
        self._set_active_view(int(window.get("active_view", 0)))
        for plane, (zoom, centre) in (window.get("zoom") or {}).items():
            view = self.slice_views.get(plane)
            if view is not None:
                view.zoom, view.centre_st = float(zoom), tuple(centre) if centre else None
                view.update()
        if self.enlarged is not None:
            self.toggle_enlarged(self.enlarged)
        enlarged = window.get("enlarged")
        if enlarged:
            self.toggle_enlarged(self.slice_views[enlarged[1]] if enlarged[0] == "slice" else self.views[enlarged[1]])
        self.set_tool(window.get("tool", "navigate"))
        cameras = [camera_from_dict(entry) for entry in state.get("cameras", [])]
        targets = self.views[:1] if self.model.cameras_linked else self.views[: self.model.view_count]
        for view, camera in zip(targets, cameras):
            camera.apply_to_vtk(view.renderer.GetActiveCamera())
        self.camera_link.flush()
