"""The workbench window's file actions: open volumes, meshes and DICOM folders (with the series choice), drag and
drop, the recent files. A mixin of :class:`ui.main_window.MainWindow`, which provides the model, the task runner
and the settings."""

from __future__ import annotations

from pathlib import Path

from qtpy.QtGui import QAction
from qtpy.QtWidgets import QFileDialog, QMessageBox

from app.io import READABLE_SUFFIXES, is_zarr_path, list_series
from app.io.meshes import MESH_SUFFIXES_READ
from app.provenance import series_choices
from app.pyramid_view import load_pyramid_for_view
from app.samples import sample_path
from app.volume import Volume
from app.workbench import load_for_workbench

from .dialogs import SeriesChooser
from .tasks import Task

MAX_RECENT = 8
VOLUME_FILTER = ("Volumes and meshes (" + " ".join(f"*{s}" for s in READABLE_SUFFIXES + tuple(MESH_SUFFIXES_READ))
                 + ");;Volumes (" + " ".join(f"*{s}" for s in READABLE_SUFFIXES) + ");;Meshes ("
                 + " ".join(f"*{s}" for s in MESH_SUFFIXES_READ) + ");;All files (*)")


class FileActions:
    # -- opening ---------------------------------------------------------------------------------------------
    def open_file_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open volume or mesh", self._last_folder(), VOLUME_FILTER)
        if path:
            self.open_path(path)

    def open_folder_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open DICOM folder", self._last_folder())
        if folder:
            self.open_path(folder)

    def open_sample(self, name: str) -> None:
        """Open a sample by short name; a sample that is not installed is a message, not an exception."""
        try:
            path = sample_path(name)
        except ValueError as exc:
            self._report_error(str(exc), "Sample not installed")
            return
        self.open_path(path)

    def open_path(self, path, series_uid: str | None = None, *, labels: bool | None = None) -> None:
        """Load a file or DICOM folder in a worker; a folder with several series asks which one first. A label map
        (detected, or ``labels=True``) opened over a volume is drawn over it."""
        path = Path(path)
        if path.is_dir() and series_uid is None and not is_zarr_path(path):  # a .zarr store is a folder too
            task = Task(f"Scanning {path.name}", lambda progress=None: list_series(path))
            task.finished.connect(lambda series: self._series_listed(path, series))
            task.failed.connect(lambda exc: self._load_error(path, exc))
            self.tasks.start(task)
            return
        loader = load_pyramid_for_view if is_zarr_path(path) else load_for_workbench  # coarse level (issue 19)
        task = Task(f"Loading {path.name}", loader, path, series_uid=series_uid, labels=labels)
        task.finished.connect(lambda volume: self._loaded(path, volume))
        task.failed.connect(lambda exc: self._load_error(path, exc))
        self.tasks.start(task)

    def _series_listed(self, path: Path, series: list[dict]) -> None:
        """Open the largest series, asking first only when another one is a real alternative (a stack of at least
        a quarter of its images, not a localizer); scripted runs never ask."""
        series = series_choices(series)
        loadable = [s for s in series if s["loadable"]]
        if not loadable:
            reasons = "; ".join(f"{s['description'] or s['series_uid']}: {s['reason']}" for s in series[:4])
            self._load_error(path, ValueError("the folder holds no DICOM image series that forms a volume"
                                              + (f" ({reasons})" if reasons else "")))
            return
        alternatives = [s for s in loadable[1:] if s["slices"] >= max(2, loadable[0]["slices"] // 4)]
        if alternatives and self.ask_for_series:
            uid = SeriesChooser.ask(str(path), series, self)
            if uid is None:
                return
        else:
            uid = loadable[0]["series_uid"]
        self.open_path(path, series_uid=uid)

    def open_other_series(self) -> None:
        """Choose another image series of the DICOM folder on show."""
        volume = self.model.base_volume
        folder = Path(volume.metadata.get("source_path", "")) if volume is not None else None
        if folder is None or not folder.is_dir():
            self._report_error("The volume on show is not a DICOM folder.", "No other series")
            return
        series = series_choices(list_series(folder))
        uid = SeriesChooser.ask(str(folder), series, self)
        if uid is not None:
            self.open_path(folder, series_uid=uid)

    def _loaded(self, path: Path, data) -> None:
        self._add_recent(path)
        message = f"Opened {path.name}"
        if isinstance(data, Volume):
            item = self.model.open_volume(data)
            warnings = data.metadata.get("warnings", [])
            if item is not self.model.base:
                message += f" as labels over {self.model.base.name}"
        else:
            warnings = self.model.add_mesh(data, path.name).metadata.get("warnings", [])
        if warnings or (isinstance(data, Volume) and data.metadata.get("interpolated_slices")):
            # Warnings stay in the Provenance panel for as long as the volume is open; show it.
            self.provenance_dock.show()
            self.provenance_dock.raise_()
            message += f" with {len(warnings)} warning(s): see the Provenance panel"
        self.statusBar().showMessage(message, 15000)
        self.volume_loaded.emit(data)

    def _load_error(self, path: Path, exc: Exception) -> None:
        message = str(exc) or type(exc).__name__
        self.load_failed.emit(message)
        self._report_error(f"Could not open {path}:\n\n{message}", title="Could not open the volume")

    def _report_error(self, message: str, title: str = "Voxelscope") -> None:
        self.statusBar().showMessage(message.splitlines()[0], 15000)
        box = QMessageBox(QMessageBox.Warning, title, message, QMessageBox.Ok, self)
        box.setObjectName("error-dialog")
        box.open()  # window-modal, does not block the event loop

    def dragEnterEvent(self, event) -> None:  # noqa: N802 - Qt override
        if event.mimeData().hasUrls():
            event.acceptProposedAction()

    def dropEvent(self, event) -> None:  # noqa: N802
        paths = [url.toLocalFile() for url in event.mimeData().urls() if url.isLocalFile()]
        if paths:
            self.open_path(paths[0])
            event.acceptProposedAction()

    def _recent(self) -> list[str]:
        value = self.settings.value("recent", [])
        if isinstance(value, str):
            value = [value]
        return [str(v) for v in (value or [])]

    def _add_recent(self, path: Path) -> None:
        recent = [str(path)] + [p for p in self._recent() if p != str(path)]
        self.settings.setValue("recent", recent[:MAX_RECENT])
        self.settings.setValue("last_folder", str(path.parent if path.is_file() else path))
        self._refresh_recent_menu()

    def _refresh_recent_menu(self) -> None:
        self.recent_menu.clear()
        recent = self._recent()
        for path in recent:
            action = QAction(path, self)
            action.triggered.connect(lambda _=False, p=path: self.open_path(p))
            self.recent_menu.addAction(action)
        self.recent_menu.setEnabled(bool(recent))

    def _last_folder(self) -> str:
        return str(self.settings.value("last_folder", str(Path.home())))
