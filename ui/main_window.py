"""The Voxelscope workbench window: a grid of linked 3D views, three slice views, the control panel, file and
export actions, and a status bar with progress and Cancel for long work."""

from __future__ import annotations

from qtpy.QtCore import QByteArray, QSettings, Qt, QTimer, Signal
from qtpy.QtGui import QAction, QActionGroup, QKeySequence
from qtpy.QtWidgets import (
    QApplication,
    QDockWidget,
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

from algorithms.common.camera import Camera
from app.modes import get_mode
from app.operations import operations
from app.pipeline import default_camera, view_inputs
from app.samples import sample_path
from app.workbench import LAYOUTS, MAX_VIEWS, WorkbenchModel

from .camera_link import CameraLink
from .controls import ControlPanel
from .render_view import RenderView
from .scene_panel import ScenePanel
from .window_export import ExportActions
from .window_files import FileActions
from .window_scene import SceneActions
from .slice_view import SliceView
from .tasks import Task, TaskRunner



class MainWindow(FileActions, ExportActions, SceneActions, QMainWindow):
    """The workbench. ``settings`` defaults to the user's Voxelscope settings (tests pass a temporary file)."""

    all_views_ready = Signal()
    volume_loaded = Signal(object)
    load_failed = Signal(str)
    operation_finished = Signal(object)  # the new scene item

    def __init__(self, settings: QSettings | None = None, parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Voxelscope")
        self.settings = settings or QSettings("Voxelscope", "Voxelscope")
        self.model = WorkbenchModel()
        self.tasks = TaskRunner(self)
        self.camera_link = CameraLink(self)
        self.active_view = 0
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
            view.options_chosen.connect(lambda index, values: self.model.set_view_options(index, **values))
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

        # Scene: the items, which one the views show
        self.scene_panel = ScenePanel(self.model)
        self.scene_panel.show_requested.connect(lambda name: self.model.show_item(self.model.scene.get(name)))
        self.scene_panel.remove_requested.connect(self._remove_item)
        self.scene_dock = QDockWidget("Scene", self)
        self.scene_dock.setObjectName("scene")
        self.scene_dock.setWidget(self.scene_panel)
        self.addDockWidget(Qt.RightDockWidgetArea, self.scene_dock)
        self._overlay_cache: dict[str, tuple] = {}

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
        self.model.item_changed.connect(self._item_changed)
        self.model.volume_changed.connect(self._volume_changed)
        self.model.scene.item_added.connect(lambda item: self._overlays_changed())
        self.model.scene.item_removed.connect(lambda item: self._overlays_changed())
        self.model.scene.item_changed.connect(lambda item: self._overlays_changed())
        self.model.iso_changed.connect(lambda iso: self._each_visible(lambda v: v.set_iso(iso)))
        self.model.transfer_function_changed.connect(
            lambda tf: self._each_visible(lambda v: v.set_transfer_function(tf)))
        self.model.layout_changed.connect(self._apply_layout)
        self.model.view_mode_changed.connect(self._view_mode_changed)
        self.model.view_options_changed.connect(lambda index, options: self.views[index].set_options(options))
        self.model.cameras_linked_changed.connect(self.camera_link.set_linked)
        self.model.cursor_changed.connect(lambda p: [v.set_cursor(p) for v in self.slice_views.values()])
        self.model.window_level_changed.connect(
            lambda w, level: [v.set_window_level(w, level) for v in self.slice_views.values()])

        self._restore_settings()
        self._apply_layout(self.model.layout)

    # -- menus ------------------------------------------------------------------------------------------------
    def _build_menus(self) -> None:
        file_menu = self.menuBar().addMenu("&File")
        self.open_action = self._action(file_menu, "&Open volume or mesh...", self.open_file_dialog,
                                        QKeySequence.Open)
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

        operations_menu = self.menuBar().addMenu("&Operations")
        group_menus: dict[str, object] = {}
        for operation in operations():
            menu = group_menus.get(operation.group)
            if menu is None:
                menu = group_menus[operation.group] = operations_menu.addMenu(operation.group)
            action = self._action(menu, operation.label + "...", lambda _=False, n=operation.name: self.run_operation(n))
            action.setToolTip(operation.description)

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

    # -- model changes -----------------------------------------------------------------------------------
    def _item_changed(self, item) -> None:
        self.setWindowTitle(f"Voxelscope - {item.name}")
        self.reset_camera("anterior", all_views=True)
        self.camera_link.flush()  # before the views get the new content, so the reset cannot arrive after it
        for index, view in enumerate(self.views):
            if index < self.model.view_count:
                self._show_in(view)

    def _show_in(self, view: RenderView) -> None:
        """Give a view the item on show, with the model's isovalue and transfer function and the view's mode."""
        model = self.model
        inputs = view_inputs(model.item, iso=model.iso if model.volume is not None else None)
        inputs.transfer_function = model.transfer_function or inputs.transfer_function
        view.show_item(inputs, model.view_modes[view.index], model.view_options[view.index])
        view.pipeline.set_overlays([item for item in model.scene if item is not model.item])

    def _volume_changed(self, volume) -> None:
        for view in self.slice_views.values():
            view.set_volume(volume, self.model.cursor, self.model.window, self.model.level)
        self._overlay_cache.clear()
        self._update_slice_overlays()

    def _view_mode_changed(self, index: int, mode: str, options: dict) -> None:
        view = self.views[index]
        if view.item is None and self.model.item is not None and index < self.model.view_count:
            self._show_in(view)
        else:
            view.set_mode(mode, self.model.view_options[index])
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
                if self.model.item is not None and (view.item is not self.model.item
                                                    or view.mode != self.model.view_modes[index]):
                    self._show_in(view)
        if layout in getattr(self, "layout_actions", {}):
            self.layout_actions[layout].setChecked(True)
        self.settings.setValue("layout", layout)

    def _each_visible(self, action) -> None:
        for view in self.views[: self.model.view_count]:
            if view.item is not None:
                action(view)

    def _iso_preview(self, iso: float) -> None:
        self._each_visible(lambda view: view.set_iso(iso, preview=True))

    def _cursor_picked(self, point) -> None:
        if self.model.base_volume is not None:
            self.model.set_cursor(point)

    def _set_active_view(self, index: int) -> None:
        self.active_view = index
        for view in self.views:
            view.setStyleSheet("" if view.index != index else "#view%d { border: 1px solid #d0a030; }" % index)

    # -- cameras ----------------------------------------------------------------------------------------------
    def reset_camera(self, side: str = "anterior", *, all_views: bool = False) -> None:
        """Look at the volume from a standard side, the whole box in view (every view following the active one)."""
        item = self.model.item
        if item is None:
            return
        view = self.views[self.active_view]
        width, height = view.plotter.ren_win.GetSize()
        camera = default_camera(item, view=side, aspect=max(width, 1) / max(height, 1),
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
            if view.isVisible() and view.item is not None:
                view.camera_moved()

    # -- readiness (scripting and tests) -----------------------------------------------------------------------
    def _view_ready(self, index: int) -> None:
        if self.views_ready():
            self.all_views_ready.emit()

    def views_ready(self) -> bool:
        visible = self.views[: self.model.view_count]
        return (self.model.item is not None and not self.camera_link.pending
                and all(view.is_ready for view in visible))

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
            view.mode_box.set_current(self.model.view_modes[index])
        self._refresh_recent_menu()

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
