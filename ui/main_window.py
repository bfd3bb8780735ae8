"""The Voxelscope workbench window: a grid of linked 3D views, three slice views, the control panel, file and
export actions, and a status bar with progress and Cancel for long work."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from qtpy.QtCore import QByteArray, QSettings, Qt, QTimer, Signal
from qtpy.QtGui import QAction, QActionGroup, QKeySequence
from qtpy.QtWidgets import (
    QApplication,
    QDockWidget,
    QFileDialog,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QWidget,
)

from algorithms.camera import Camera
from app.io import READABLE_SUFFIXES, FileExistsRefusal, list_series
from app.meshing import export_mesh, sidecar_path
from app.modes import get_mode
from app.render_job import write_png
from app.rendering import default_camera
from app.samples import sample_path
from app.workbench import LAYOUTS, MAX_VIEWS, WorkbenchModel, load_for_workbench

from .camera_link import CameraLink
from .controls import ControlPanel
from .dialogs import ExportOptionsDialog, SeriesChooser
from .render_view import RenderView
from .slice_view import SliceView
from .tasks import Task, TaskRunner

MAX_RECENT = 8
VOLUME_FILTER = "Volumes (" + " ".join(f"*{s}" for s in READABLE_SUFFIXES) + ");;All files (*)"
MESH_FILTER = "STL (*.stl);;PLY (*.ply);;OBJ (*.obj);;VTK polydata (*.vtp)"


class MainWindow(QMainWindow):
    """The workbench. ``settings`` defaults to the user's Voxelscope settings (tests pass a temporary file)."""

    all_views_ready = Signal()
    volume_loaded = Signal(object)
    load_failed = Signal(str)

    def __init__(self, settings: QSettings | None = None, parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Voxelscope")
        self.settings = settings or QSettings("Voxelscope", "Voxelscope")
        self.model = WorkbenchModel()
        self.tasks = TaskRunner(self)
        self.camera_link = CameraLink(self)
        self.active_view = 0
        self.image = None  # shared vtkImageData of the volume (volume frame)
        self.ask_for_series = True  # False in scripted runs: open the largest series without a dialog

        # Views
        self.views: list[RenderView] = []
        self.grid_widget = QWidget()
        self.grid = QGridLayout(self.grid_widget)
        self.grid.setContentsMargins(0, 0, 0, 0)
        self.grid.setSpacing(2)
        for index in range(MAX_VIEWS):
            view = RenderView(index, self.tasks, self.grid_widget)
            view.plotter.setAcceptDrops(False)  # drops open volumes in the window, not meshes in a view
            view.mode_chosen.connect(self.model.set_view_mode)
            view.ready.connect(self._view_ready)
            view.activated.connect(self._set_active_view)
            view.failed.connect(self._report_error)
            self.camera_link.attach(view)
            self.views.append(view)
        self.setCentralWidget(self.grid_widget)
        self.camera_link.camera_moved.connect(self._camera_moved)

        # Slice views
        slices = QWidget()
        slice_layout = QHBoxLayout(slices)
        slice_layout.setContentsMargins(0, 0, 0, 0)
        self.slice_views = {plane: SliceView(plane) for plane in ("axial", "coronal", "sagittal")}
        for view in self.slice_views.values():
            view.cursor_picked.connect(self._cursor_picked)
            view.window_level_dragged.connect(self.model.set_window_level)
            slice_layout.addWidget(view)
        self.slice_dock = QDockWidget("Slices", self)
        self.slice_dock.setObjectName("slices")
        self.slice_dock.setWidget(slices)
        self.addDockWidget(Qt.BottomDockWidgetArea, self.slice_dock)

        # Controls
        self.controls = ControlPanel(self.model)
        self.controls.iso_preview.connect(self._iso_preview)
        self.controls.reset_camera.connect(self.reset_camera)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.controls)
        self.control_dock = QDockWidget("Controls", self)
        self.control_dock.setObjectName("controls")
        self.control_dock.setWidget(scroll)
        self.control_dock.setMinimumWidth(300)
        self.addDockWidget(Qt.RightDockWidgetArea, self.control_dock)

        # Status bar: message, progress, cancel
        self.progress = QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setTextVisible(False)
        self.progress.setMaximumWidth(220)
        self._progress_value = 0.0
        # Progress is shown at most five times a second: every repaint of this window also composes the 3D
        # views, which costs real time with software OpenGL.
        self._progress_timer = QTimer(self)
        self._progress_timer.setInterval(200)
        self._progress_timer.timeout.connect(self._show_progress)
        self.progress.setEnabled(False)
        self.progress_label = QLabel("")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setObjectName("cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.tasks.cancel_all)
        self.statusBar().addPermanentWidget(self.progress_label)
        self.statusBar().addPermanentWidget(self.progress)
        self.statusBar().addPermanentWidget(self.cancel_button)
        self.tasks.started.connect(self._task_started)
        self.tasks.ended.connect(self._task_ended)

        self._build_menus()
        self.setAcceptDrops(True)

        # Model -> window
        self.model.volume_changed.connect(self._volume_changed)
        self.model.iso_changed.connect(lambda iso: self._each_visible(lambda v: v.set_iso(iso)))
        self.model.transfer_function_changed.connect(
            lambda tf: self._each_visible(lambda v: v.set_transfer_function(tf)))
        self.model.layout_changed.connect(self._apply_layout)
        self.model.view_mode_changed.connect(self._view_mode_changed)
        self.model.cameras_linked_changed.connect(self.camera_link.set_linked)
        self.model.cursor_changed.connect(lambda p: [v.set_cursor(p) for v in self.slice_views.values()])
        self.model.window_level_changed.connect(
            lambda w, level: [v.set_window_level(w, level) for v in self.slice_views.values()])

        self._restore_settings()
        self._apply_layout(self.model.layout)

    # -- menus ------------------------------------------------------------------------------------------------
    def _build_menus(self) -> None:
        file_menu = self.menuBar().addMenu("&File")
        self.open_action = self._action(file_menu, "&Open volume...", self.open_file_dialog, QKeySequence.Open)
        self._action(file_menu, "Open &DICOM folder...", self.open_folder_dialog, "Ctrl+D")
        self._action(file_menu, "Open another series of this &folder...", self.open_other_series)
        self._action(file_menu, "Open &sample CT", lambda: self.open_path(sample_path("ct")))
        self._action(file_menu, "Open sample &MRI", lambda: self.open_path(sample_path("mri")))
        self.recent_menu = file_menu.addMenu("&Recent")
        file_menu.addSeparator()
        self._action(file_menu, "&Export mesh of the active view...", self.export_mesh, "Ctrl+E")
        self._action(file_menu, "Save screenshot of the active &view...", self.save_view_screenshot)
        self._action(file_menu, "Save screenshot of &all views...", self.save_grid_screenshot, "Ctrl+Shift+S")
        file_menu.addSeparator()
        self._action(file_menu, "&Quit", self.close, QKeySequence.Quit)

        view_menu = self.menuBar().addMenu("&View")
        group = QActionGroup(self)
        self.layout_actions = {}
        for name in LAYOUTS:
            action = self._action(view_menu, f"Layout {name}", lambda _=False, n=name: self.model.set_layout(n))
            action.setCheckable(True)
            group.addAction(action)
            self.layout_actions[name] = action
        view_menu.addSeparator()
        self.link_action = self._action(view_menu, "&Link cameras", self.model.set_cameras_linked)
        self.link_action.setCheckable(True)
        self.link_action.setChecked(True)
        self.model.cameras_linked_changed.connect(self.link_action.setChecked)
        self.parallel_action = self._action(view_menu, "&Parallel projection", self.set_parallel_projection, "P")
        self.parallel_action.setCheckable(True)
        self._action(view_menu, "&Reset camera", lambda: self.reset_camera("anterior"), "R")
        for name in ("anterior", "posterior", "left", "right", "superior", "inferior"):
            self._action(view_menu, f"{name.capitalize()} view", lambda _=False, n=name: self.reset_camera(n))
        help_menu = self.menuBar().addMenu("&Help")
        self._action(help_menu, "&About Voxelscope", self._about)

    def _action(self, menu, text, slot, shortcut=None) -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcut(QKeySequence(shortcut))
        action.triggered.connect(slot)
        menu.addAction(action)
        return action

    def _about(self) -> None:
        from app import __version__

        QMessageBox.about(self, "About Voxelscope", f"Voxelscope {__version__}\nA workbench for medical and "
                                                    "scientific volumes: render modes side by side, mesh export.")

    # -- opening ---------------------------------------------------------------------------------------------
    def open_file_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open volume", self._last_folder(), VOLUME_FILTER)
        if path:
            self.open_path(path)

    def open_folder_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open DICOM folder", self._last_folder())
        if folder:
            self.open_path(folder)

    def open_path(self, path, series_uid: str | None = None) -> None:
        """Load a file or DICOM folder in a worker; a folder with several series asks which one first."""
        path = Path(path)
        if path.is_dir() and series_uid is None:
            task = Task(f"Scanning {path.name}", lambda progress=None: list_series(path))
            task.finished.connect(lambda series: self._series_listed(path, series))
            task.failed.connect(lambda exc: self._load_error(path, exc))
            self.tasks.start(task)
            return
        task = Task(f"Loading {path.name}", load_for_workbench, path, series_uid=series_uid)
        task.finished.connect(lambda volume: self._loaded(path, volume))
        task.failed.connect(lambda exc: self._load_error(path, exc))
        self.tasks.start(task)

    def _series_listed(self, path: Path, series: list[dict]) -> None:
        """Open the largest series, asking first only when another one is a real alternative (a stack of at least
        a quarter of its images, not a localizer); scripted runs never ask."""
        if not series:
            self._load_error(path, ValueError("the folder holds no DICOM image series"))
            return
        alternatives = [s for s in series[1:] if s["slices"] >= max(2, series[0]["slices"] // 4)]
        if alternatives and self.ask_for_series:
            uid = SeriesChooser.ask(str(path), series, self)
            if uid is None:
                return
        else:
            uid = series[0]["series_uid"]
        self.open_path(path, series_uid=uid)

    def open_other_series(self) -> None:
        """Choose another image series of the DICOM folder on show."""
        volume = self.model.volume
        folder = Path(volume.metadata.get("source_path", "")) if volume is not None else None
        if folder is None or not folder.is_dir():
            self._report_error("The volume on show is not a DICOM folder.", "No other series")
            return
        series = list_series(folder)
        uid = SeriesChooser.ask(str(folder), series, self)
        if uid is not None:
            self.open_path(folder, series_uid=uid)

    def _loaded(self, path: Path, volume) -> None:
        self._add_recent(path)
        self.model.set_volume(volume)
        warnings = volume.metadata.get("warnings", [])
        self.statusBar().showMessage(
            f"Opened {path.name}" + (f" with {len(warnings)} warning(s): {warnings[0]}" if warnings else ""), 15000)
        self.volume_loaded.emit(volume)

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

    # -- model changes -----------------------------------------------------------------------------------
    def _volume_changed(self, volume) -> None:
        self.image = volume.to_vtk(local=True)
        self.setWindowTitle(f"Voxelscope - {Path(volume.metadata.get('source_path', '')).name}")
        self.reset_camera("anterior", all_views=True)
        self.camera_link.flush()  # before the views get the new content, so the reset cannot arrive after it
        for index, view in enumerate(self.views):
            if index < self.model.view_count:
                view.set_volume(volume, self.image, self.model.view_modes[index], self.model.iso,
                                self.model.transfer_function)
        for view in self.slice_views.values():
            view.set_volume(volume, self.model.cursor, self.model.window, self.model.level)

    def _view_mode_changed(self, index: int, mode: str) -> None:
        view = self.views[index]
        if view.volume is None and self.model.volume is not None and index < self.model.view_count:
            view.set_volume(self.model.volume, self.image, mode, self.model.iso, self.model.transfer_function)
        else:
            view.set_mode(mode)
        self.settings.setValue("modes", ",".join(self.model.view_modes))

    def _apply_layout(self, layout: str) -> None:
        rows, columns = LAYOUTS[layout]
        for view in self.views:
            self.grid.removeWidget(view)
        for index, view in enumerate(self.views):
            visible = index < rows * columns
            view.setVisible(visible)
            if visible:
                self.grid.addWidget(view, index // columns, index % columns)
                if self.model.volume is not None and (view.volume is not self.model.volume
                                                      or view.mode != self.model.view_modes[index]):
                    view.set_volume(self.model.volume, self.image, self.model.view_modes[index], self.model.iso,
                                    self.model.transfer_function)
        if layout in getattr(self, "layout_actions", {}):
            self.layout_actions[layout].setChecked(True)
        self.settings.setValue("layout", layout)

    def _each_visible(self, action) -> None:
        for view in self.views[: self.model.view_count]:
            if view.volume is not None:
                action(view)

    def _iso_preview(self, iso: float) -> None:
        for view in self.views[: self.model.view_count]:
            if view.volume is not None and get_mode(view.mode).kind == "surface":
                view.set_iso(iso, preview=True)

    def _cursor_picked(self, point) -> None:
        if self.model.volume is not None:
            self.model.set_cursor(point)

    def _set_active_view(self, index: int) -> None:
        self.active_view = index
        for view in self.views:
            view.setStyleSheet("" if view.index != index else "#view%d { border: 1px solid #d0a030; }" % index)

    # -- cameras ----------------------------------------------------------------------------------------------
    def reset_camera(self, side: str = "anterior", *, all_views: bool = False) -> None:
        """Look at the volume from a standard side, the whole box in view (every view following the active one)."""
        volume = self.model.volume
        if volume is None:
            return
        view = self.views[self.active_view]
        width, height = view.plotter.ren_win.GetSize()
        camera = default_camera(volume, view=side, aspect=max(width, 1) / max(height, 1),
                                parallel=self.parallel_action.isChecked())
        targets = self.views if all_views else self.camera_link.views_following(view)
        for target in targets:
            camera.apply_to_vtk(target.renderer.GetActiveCamera())

    def set_parallel_projection(self, parallel: bool) -> None:
        """Switch the cameras the active view follows between parallel and perspective projection, keeping what
        is shown at the focal point the same size."""
        view = self.views[self.active_view]
        for target in self.camera_link.views_following(view):
            camera = target.renderer.GetActiveCamera()
            if bool(camera.GetParallelProjection()) == bool(parallel):
                continue
            if parallel:
                camera.SetParallelScale(Camera.from_vtk(camera).as_parallel().parallel_scale)
            camera.SetParallelProjection(int(bool(parallel)))
        self.parallel_action.setChecked(bool(parallel))

    def _camera_moved(self, source) -> None:
        targets = self.views if source is None else self.camera_link.views_following(source)
        for view in targets:
            if view.isVisible() and view.volume is not None:
                view.camera_moved()

    # -- readiness (scripting and tests) -----------------------------------------------------------------------
    def _view_ready(self, index: int) -> None:
        if self.views_ready():
            self.all_views_ready.emit()

    def views_ready(self) -> bool:
        visible = self.views[: self.model.view_count]
        return (self.model.volume is not None and not self.camera_link.pending
                and all(view.is_ready for view in visible))

    # -- export and screenshots --------------------------------------------------------------------------------
    def _surface_view(self) -> RenderView | None:
        active = self.views[self.active_view]
        if active.isVisible() and active.current_surface() is not None:
            return active
        for view in self.views[: self.model.view_count]:
            if view.current_surface() is not None:
                return view
        return None

    def export_mesh(self) -> None:
        """Export the surface of the active view (or the first surface view) with its JSON sidecar."""
        view = self._surface_view()
        if view is None:
            self._report_error("No view shows a finished surface. Switch a view to a surface mode (for example "
                               "flying-edges) and wait for it to be built, then export.", "Nothing to export")
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export mesh", self._last_folder(), MESH_FILTER)
        if not path:
            return
        path = Path(path)
        if path.suffix.lower() not in (".stl", ".ply", ".obj", ".vtp"):
            path = path.with_suffix(".stl")
        # The file dialog confirmed replacing the mesh file itself; the sidecar is asked about separately.
        overwrite = path.exists()
        side = sidecar_path(path)
        if side.exists() and not self._confirm(f"{side.name} already exists. Replace it?"):
            return
        overwrite = overwrite or side.exists()
        options = ExportOptionsDialog.ask(str(path), self)
        if options is None:
            return
        close_edges = options.get("close_edges", False)
        volume, result = self.model.volume, None if close_edges else view.current_surface()
        task = Task(f"Exporting {path.name}", export_mesh, volume, path, method=view.mode, iso=view.iso,
                    coordinates=options["coordinates"], cleanup=options["cleanup"], close_edges=close_edges,
                    overwrite=overwrite, result=result)
        task.finished.connect(lambda export: self.statusBar().showMessage(
            f"Wrote {export.paths[0]} ({export.written['triangles']:,} triangles, {options['coordinates']} mm) and its "
            f"sidecar", 15000))
        task.failed.connect(lambda exc: self._report_error(f"Could not export {path}:\n\n{exc}", "Export failed"))
        self.tasks.start(task)

    def _confirm(self, question: str) -> bool:
        return QMessageBox.question(self, "Voxelscope", question) == QMessageBox.Yes

    def grab_views(self) -> np.ndarray:
        """All visible views in their grid as one ``(h, w, 3)`` uint8 image."""
        rows, columns = LAYOUTS[self.model.layout]
        captures = [view.capture() for view in self.views[: rows * columns]]
        height = max(c.shape[0] for c in captures)
        width = max(c.shape[1] for c in captures)
        canvas = np.zeros((rows * height, columns * width, 3), dtype=np.uint8)
        for index, capture in enumerate(captures):
            r, c = divmod(index, columns)
            canvas[r * height: r * height + capture.shape[0], c * width: c * width + capture.shape[1]] = capture
        return canvas

    def grab_window(self) -> np.ndarray:
        """The whole window (controls, views, slices) as ``(h, w, 3)`` uint8."""
        from qtpy.QtGui import QImage

        image = self.grab().toImage().convertToFormat(QImage.Format_RGB888)
        width, height = image.width(), image.height()
        buffer = np.frombuffer(image.constBits(), dtype=np.uint8, count=image.sizeInBytes())
        return buffer.reshape(height, image.bytesPerLine())[:, : width * 3].reshape(height, width, 3).copy()

    def save_view_screenshot(self) -> None:
        self._save_png(lambda: self.views[self.active_view].capture(), "Save view screenshot")

    def save_grid_screenshot(self) -> None:
        self._save_png(self.grab_views, "Save screenshot of all views")

    def _save_png(self, grab, title: str) -> None:
        path, _ = QFileDialog.getSaveFileName(self, title, self._last_folder(), "PNG image (*.png)")
        if not path:
            return
        path = Path(path) if path.lower().endswith(".png") else Path(path + ".png")
        try:
            write_png(grab(), path, overwrite=path.exists())  # the dialog asked before replacing
        except (OSError, ValueError, FileExistsRefusal) as exc:
            self._report_error(f"Could not save {path}:\n\n{exc}")
            return
        self.statusBar().showMessage(f"Saved {path}", 10000)

    # -- progress ------------------------------------------------------------------------------------------------
    def _task_started(self, task: Task) -> None:
        task.progress.connect(self._note_progress)
        self._update_progress_widgets()

    def _note_progress(self, fraction: float) -> None:
        self._progress_value = fraction

    def _show_progress(self) -> None:
        value = int(self._progress_value * 100)
        if value != self.progress.value():
            self.progress.setValue(value)

    def _task_ended(self, task: Task) -> None:
        self._update_progress_widgets()

    def _update_progress_widgets(self) -> None:
        # The widgets stay in place (enabled or not) so the views never resize, and redraw, because of them.
        running = self.tasks.running
        busy = bool(running)
        self.progress.setEnabled(busy)
        self.cancel_button.setEnabled(busy)
        self.progress_label.setText(running[-1].label if busy else "")
        if busy and not self._progress_timer.isActive():
            self._progress_value = 0.0
            self._progress_timer.start()
        if not busy:
            self._progress_timer.stop()
            self.progress.setValue(0)
            if self.views_ready():
                self.all_views_ready.emit()

    # -- settings --------------------------------------------------------------------------------------------
    def _restore_settings(self) -> None:
        geometry = self.settings.value("geometry")
        if isinstance(geometry, QByteArray) and not geometry.isEmpty():
            self.restoreGeometry(geometry)
        else:
            self.resize(1500, 950)
        state = self.settings.value("state")
        if isinstance(state, QByteArray) and not state.isEmpty():
            self.restoreState(state)
        layout = self.settings.value("layout", "2x2")
        if layout in LAYOUTS:
            self.model.layout = layout
        modes = str(self.settings.value("modes", "") or "").split(",")
        for index, mode in enumerate(modes[:MAX_VIEWS]):
            try:
                get_mode(mode)
            except ValueError:
                continue
            self.model.view_modes[index] = mode
        for index, view in enumerate(self.views):
            view.set_mode(self.model.view_modes[index])
        self._refresh_recent_menu()

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

    def closeEvent(self, event) -> None:  # noqa: N802
        self.settings.setValue("geometry", self.saveGeometry())
        self.settings.setValue("state", self.saveState())
        self.settings.setValue("modes", ",".join(self.model.view_modes))
        self.settings.sync()
        self.tasks.cancel_all()
        self.tasks.wait(10000)
        for view in self.views:
            view.shutdown()
        super().closeEvent(event)


def application(argv=None) -> QApplication:
    """The running QApplication, created with Voxelscope's names if there is none yet."""
    app = QApplication.instance()
    if app is None:
        app = QApplication(list(argv or ["voxelscope"]))
        app.setOrganizationName("Voxelscope")
        app.setApplicationName("Voxelscope")
    return app
