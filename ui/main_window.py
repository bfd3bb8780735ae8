"""The Voxelscope workbench window: a grid of linked 3D views beside three large slice views (any view can be shown
alone), the docks (controls, scene, measurements, provenance), file, session, label and export actions, measuring
tools, undo/redo, and a status bar with progress and Cancel for long work (:mod:`.task_progress`).

The window is assembled from mixins, one concern each: :mod:`.window_layout` (views, docks, View menu, the default
views), :mod:`.window_files` (opening), :mod:`.window_export` (meshes, screenshots), :mod:`.window_scene`
(operations, overlays), :mod:`.window_tools` (measurements, labels, provenance, undo), :mod:`.window_cutaways`
(cut-away tools) and :mod:`.window_session` (sessions).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from qtpy.QtCore import QByteArray, QSettings, Signal
from qtpy.QtGui import QAction, QActionGroup, QKeySequence
from qtpy.QtWidgets import QApplication, QMainWindow, QMessageBox

from algorithms.common.camera import Camera
from app.framing import framing_camera
from app.modes import get_mode
from app.operations import operations
from app.pipeline import view_inputs
from app.workbench import LAYOUTS, MAX_VIEWS, WorkbenchModel

from . import gui_thread_gc
from .camera_link import CameraLink
from .render_view import RenderView
from .task_progress import TaskProgress
from .tasks import TaskRunner
from .window_cutaways import CutawayActions
from .window_export import ExportActions
from .window_files import FileActions
from .window_layout import LayoutActions
from .window_scene import SceneActions
from .window_session import SessionActions
from .window_tools import ToolActions


class MainWindow(FileActions, ExportActions, SceneActions, LayoutActions, ToolActions, SessionActions, CutawayActions,
                 QMainWindow):
    """The workbench. ``settings`` defaults to the user's Voxelscope settings (tests pass a temporary file)."""

    all_views_ready = Signal()
    volume_loaded = Signal(object)
    load_failed = Signal(str)
    operation_finished = Signal(object)  # the new scene item
    session_opened = Signal(str)  # the session file, once its data and state are restored

    def __init__(self, settings: QSettings | None = None, parent=None) -> None:
        super().__init__(parent)
        gui_thread_gc.install()  # cycles (views, props, Qt wrappers) are only ever freed on this thread
        self.setWindowTitle("Voxelscope")
        self.settings = settings or QSettings("Voxelscope", "Voxelscope")
        self.model = WorkbenchModel()
        self.tasks = TaskRunner(self)
        self.camera_link = CameraLink(self)
        self.active_view = 0
        self.ask_for_series = True  # False in scripted runs: open the largest series without a dialog

        self.views: list[RenderView] = []
        for index in range(MAX_VIEWS):
            view = RenderView(index, self.tasks)
            view.plotter.setAcceptDrops(False)  # drops open volumes in the window, not meshes in a view
            view.mode_chosen.connect(self.model.set_view_mode)
            view.options_chosen.connect(lambda index, values: self.model.set_view_options(index, **values))
            view.ready.connect(self._view_ready)
            view.activated.connect(self._set_active_view)
            view.failed.connect(self._report_error)
            self.camera_link.attach(view)
            self.views.append(view)
        self.camera_link.camera_moved.connect(self._camera_moved)
        self._build_views()  # window_layout: grid of 3D views, slice views, splitter, docks
        self.task_progress = TaskProgress(self.tasks, self.statusBar(), self)
        self.task_progress.idle.connect(self._tasks_idle)
        self.progress, self.cancel_button = self.task_progress.bar, self.task_progress.cancel_button
        self._build_tools()  # window_tools: undo stack, measuring tools, panels
        self._build_cutaways()  # window_cutaways: cut-away tools, their widgets and list (issue 15)
        self._build_menus()
        self.setAcceptDrops(True)
        from .window_pyramid import PyramidRefiner

        self.pyramid = PyramidRefiner(self)  # refines a large pyramid's region in view when zoomed (issue 19)

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
        self.model.cursor_changed.connect(self._cursor_changed)
        self.model.slice_rotation_changed.connect(self._rotation_changed)
        self.model.slice_display_changed.connect(self._slice_display_changed)
        self.model.window_level_changed.connect(
            lambda w, level: [v.set_window_level(w, level) for v in self.slice_views.values()])
        self.model.notice.connect(lambda text: self.statusBar().showMessage(text, 30000))

        self._remember_default_layout()
        self._restore_settings()
        self._apply_layout(self.model.layout)

    # -- menus ------------------------------------------------------------------------------------------------
    def _build_menus(self) -> None:
        file_menu = self.menuBar().addMenu("&File")
        self.open_action = self._action(file_menu, "&Open volume or mesh...", self.open_file_dialog,
                                        QKeySequence.Open)
        self._action(file_menu, "Open &DICOM folder...", self.open_folder_dialog, "Ctrl+D")
        self.other_series_action = self._action(file_menu, "Open another series of this &folder...",
                                                self.open_other_series)
        self.other_series_action.setEnabled(False)
        self._action(file_menu, "Open &label volume (atlas, segmentation)...", self.open_labels_dialog, "Ctrl+L")
        self._action(file_menu, "Load &colour table for the labels...", self.load_color_table_dialog)
        self._action(file_menu, "Open &sample CT", lambda: self.open_sample("ct"))
        self._action(file_menu, "Open sample &MRI", lambda: self.open_sample("mri"))
        self.recent_menu = file_menu.addMenu("&Recent")
        file_menu.addSeparator()
        self._action(file_menu, "Open s&ession...", self.open_session_dialog, "Ctrl+Shift+O")
        self._action(file_menu, "Sa&ve session...", self.save_session_dialog, "Ctrl+Shift+V")
        file_menu.addSeparator()
        self._action(file_menu, "&Export mesh of the active view...", self.export_mesh, "Ctrl+E")
        self._action(file_menu, "Export one mesh &per label...", self.export_label_meshes_dialog)
        self._action(file_menu, "Export &cropped volume (keep box)...", self.export_cropped_volume_dialog)
        self._action(file_menu, "Export &measurements as CSV...", self.export_measurements_dialog)
        self._action(file_menu, "Save screenshot of the active &view...", self.save_view_screenshot)
        self._action(file_menu, "Save screenshot of &all views...", self.save_grid_screenshot, "Ctrl+Shift+S")
        file_menu.addSeparator()
        self._action(file_menu, "&Quit", self.close, QKeySequence.Quit)

        edit_menu = self.menuBar().addMenu("&Edit")
        edit_menu.addAction(self.undo_action)
        edit_menu.addAction(self.redo_action)

        operations_menu = self.menuBar().addMenu("&Operations")
        group_menus: dict[str, object] = {}
        for operation in operations():
            menu = group_menus.get(operation.group)
            if menu is None:
                menu = group_menus[operation.group] = operations_menu.addMenu(operation.group)
            action = self._action(menu, operation.label + "...", lambda _=False, n=operation.name: self.run_operation(n))
            action.setToolTip(operation.description)

        measure_menu = self.menuBar().addMenu("&Measure")
        for action in self.tool_actions.values():
            measure_menu.addAction(action)
        measure_menu.addSeparator()
        self._action(measure_menu, "&Statistics inside a mask...", self.mask_statistics_dialog)

        view_menu = self.menuBar().addMenu("&View")
        group = QActionGroup(self)
        self.layout_actions = {}
        for name in LAYOUTS:
            action = self._action(view_menu, f"Layout {name}", lambda _=False, n=name: self.model.set_layout(n))
            action.setCheckable(True)
            group.addAction(action)
            self.layout_actions[name] = action
        self.enlarge_action = self._action(view_menu, "&One big view (the active view alone)",
                                           lambda: self.toggle_enlarged(self._active_widget()), "F11")
        view_menu.addSeparator()
        for dock in self.docks:
            view_menu.addAction(dock.toggleViewAction())
        view_menu.addAction(self.tools_toolbar.toggleViewAction())
        self.slices_action = self._action(view_menu, "Slice views", self._toggle_slice_column)
        self.slices_action.setCheckable(True)
        self.slices_action.setChecked(True)
        self._action(view_menu, "Reset &layout", self.reset_window_layout)
        self._action(view_menu, "Use these views as the &default", self.save_default_views)
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
        self._action(view_menu, "Reset &oblique slices", lambda: self.model.set_slice_rotation(np.eye(3)))
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
        inputs = replace(inputs, transfer_function=model.transfer_function or inputs.transfer_function)
        if getattr(model.item, "volume", None) is not None:  # cut-away tools (issue 15)
            inputs = replace(inputs, tools=tuple(model.cutaways.tools), cut_evaluation=model.cutaways.evaluation)
        view.show_item(inputs, model.view_modes[view.index], model.view_options[view.index])
        view.pipeline.set_overlays([item for item in model.scene if item is not model.item])

    def _volume_changed(self, volume) -> None:
        table = volume.metadata.get("label_table")
        for view in self.slice_views.values():
            view.set_rotation(self.model.slice_rotation)
            view.set_volume(volume, self.model.cursor, self.model.window, self.model.level, table=table)
        source = volume.metadata.get("source_path", "")
        self.other_series_action.setEnabled(volume.metadata.get("source_format", "").startswith("DICOM")
                                            and bool(source))
        self._overlay_cache.clear()
        self._update_slice_overlays()
        self._update_slice_planes()
        self.provenance_panel.show_volume(volume)

    def _view_mode_changed(self, index: int, mode: str, options: dict) -> None:
        view = self.views[index]
        if view.item is None and self.model.item is not None and index < self.model.view_count:
            self._show_in(view)
        else:
            view.set_mode(mode, self.model.view_options[index])

    def _each_visible(self, action) -> None:
        for view in self.views[: self.model.view_count]:
            if view.item is not None:
                action(view)

    def _iso_preview(self, iso: float) -> None:
        self._each_visible(lambda view: view.set_iso(iso, preview=True))

    def _cursor_picked(self, point) -> None:
        if self.model.base_volume is not None:
            self.model.set_cursor(point)

    def _cursor_changed(self, point) -> None:
        for view in self.slice_views.values():
            view.set_cursor(point)
        self._update_slice_planes()

    def _rotation_changed(self, rotation) -> None:
        for view in self.slice_views.values():
            view.set_rotation(rotation)
        self._update_slice_planes()

    def _slice_display_changed(self) -> None:
        for view in self.slice_views.values():
            view.set_display(self.model.interpolation, self.model.label_opacity)

    def _update_slice_planes(self) -> None:
        """The crosshair's planes drawn in every 3D view (outlines where they cut the volume)."""
        from app.slices import PLANE_COLORS, plane_outlines_polydata

        volume = self.model.base_volume
        if volume is None:
            return
        outlines = plane_outlines_polydata(volume, self.model.cursor, self.model.slice_rotation)
        for view in self.views:
            view.set_slice_planes(outlines, PLANE_COLORS)

    def _set_active_view(self, index: int) -> None:
        self.active_view = index
        for view in self.views:
            view.setStyleSheet("" if view.index != index else "#view%d { border: 1px solid #d0a030; }" % index)

    # -- cameras ----------------------------------------------------------------------------------------------
    def reset_camera(self, side: str = "anterior", *, all_views: bool = False) -> None:
        """Look at the object from a standard side, fitted tightly (every view following the active one)."""
        item = self.model.item
        if item is None:
            return
        view = self.views[self.active_view]
        width, height = view.plotter.ren_win.GetSize()
        camera = framing_camera(item, iso=self.model.iso if self.model.volume is not None else None,
                                transfer_function=self.model.transfer_function, view=side,
                                aspect=max(width, 1) / max(height, 1), parallel=self.parallel_action.isChecked())
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
        """Every 3D view on show has drawn the full-quality frame of its current content."""
        visible = [view for view in self.views[: self.model.view_count] if not view.isHidden()]
        return (self.model.item is not None and not self.camera_link.pending
                and all(view.is_ready for view in visible))

    def _tasks_idle(self) -> None:
        if self.views_ready():
            self.all_views_ready.emit()

    def settle_layout(self) -> None:
        """Let every pending layout request and paint of the window's widgets (panels, docks, slice views) run."""
        from qtpy.QtCore import QEvent

        app = QApplication.instance()
        for _ in range(3):
            app.sendPostedEvents(None, QEvent.LayoutRequest)
            app.processEvents()

    def fully_ready(self) -> bool:
        """Ready for a screenshot: every 3D view drew its full-quality frame, no background work is left, every
        slice view painted its current image, every dock on show has its size."""
        if not self.views_ready() or self.tasks.running:
            return False
        for view in self.slice_views.values():
            if view.isVisible() and view.volume is not None and not view.painted:
                return False
        for dock in self.docks:
            if dock.isVisible() and not dock.isFloating() and min(dock.widget().width(), dock.widget().height()) < 2:
                return False
        return True

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
        self.settings.sync()
        self.pyramid.shutdown()  # before the tasks: a region read must not reach the views being shut down
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

