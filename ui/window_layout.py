"""The workbench window's layout: the grid of 3D views beside a column of three large slice views (a splitter the
user can drag), "one big view" for any of them, the docks (controls, scene, measurements, provenance) with their
View-menu entries, and Reset layout. A mixin of :class:`ui.main_window.MainWindow`."""

from __future__ import annotations

from qtpy.QtCore import Qt
from qtpy.QtWidgets import QDockWidget, QGridLayout, QScrollArea, QSplitter, QVBoxLayout, QWidget

from app.workbench import LAYOUTS

from .controls import ControlPanel
from .scene_panel import ScenePanel
from .slice_view import SliceView

SPLITTER_SHARES = (2, 1)  # 3D views : slice views


class LayoutActions:
    def _build_views(self) -> None:
        self.grid_widget = QWidget()
        self.grid = QGridLayout(self.grid_widget)
        self.grid.setContentsMargins(0, 0, 0, 0)
        self.grid.setSpacing(2)
        for view in self.views:
            view.setParent(self.grid_widget)
            view.enlarge_requested.connect(self.toggle_enlarged)

        self.slice_column = QWidget()
        self.slice_column.setObjectName("slice-column")
        column = QVBoxLayout(self.slice_column)
        column.setContentsMargins(0, 0, 0, 0)
        column.setSpacing(2)
        self.slice_views = {plane: SliceView(plane) for plane in ("axial", "coronal", "sagittal")}
        for view in self.slice_views.values():
            view.cursor_picked.connect(self._cursor_picked)
            view.window_level_dragged.connect(self.model.set_window_level)
            view.rotate_requested.connect(self.model.rotate_slices)
            view.enlarge_requested.connect(self.toggle_enlarged)
            column.addWidget(view, 1)

        self.splitter = QSplitter(Qt.Horizontal)
        self.splitter.setObjectName("views-splitter")
        self.splitter.addWidget(self.grid_widget)
        self.splitter.addWidget(self.slice_column)
        self.splitter.setChildrenCollapsible(False)
        for index, share in enumerate(SPLITTER_SHARES):
            self.splitter.setStretchFactor(index, share)
        self._shares_applied = False
        self.setCentralWidget(self.splitter)
        self.enlarged = None  # the view shown alone, or None

        self.controls = ControlPanel(self.model)
        self.controls.iso_preview.connect(self._iso_preview)
        self.controls.reset_camera.connect(self.reset_camera)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.controls)
        self.control_dock = self._dock("Controls", "controls", scroll, Qt.RightDockWidgetArea)
        self.control_dock.setMinimumWidth(300)

        self.scene_panel = ScenePanel(self.model)
        self.scene_panel.show_requested.connect(lambda name: self.model.show_item(self.model.scene.get(name)))
        self.scene_panel.remove_requested.connect(self._remove_item)
        self.scene_dock = self._dock("Scene", "scene", self.scene_panel, Qt.RightDockWidgetArea)
        self._overlay_cache: dict[str, tuple] = {}

    def _dock(self, title: str, name: str, widget, area) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        dock.setWidget(widget)
        self.addDockWidget(area, dock)
        if not hasattr(self, "docks"):
            self.docks = []
        self.docks.append(dock)
        return dock

    def _remember_default_layout(self) -> None:
        """The dock arrangement as built, for View > Reset layout (taken before saved settings are restored)."""
        self._default_state = self.saveState()

    def reset_window_layout(self) -> None:
        """Every dock back in its place, the slice views shown, no view enlarged, the splitter at its shares."""
        if self.enlarged is not None:
            self.toggle_enlarged(self.enlarged)
        self.restoreState(self._default_state)
        for dock in self.docks:
            dock.show()
        self.slice_column.show()
        self.slices_action.setChecked(True)
        self._apply_splitter_shares()

    def _apply_splitter_shares(self) -> None:
        total = sum(self.splitter.sizes()) or self.splitter.width()
        self.splitter.setSizes([total * share // sum(SPLITTER_SHARES) for share in SPLITTER_SHARES])

    def showEvent(self, event) -> None:  # noqa: N802 - Qt override
        super().showEvent(event)
        if not self._shares_applied:  # the first time the window has its size: 3D views 2/3, slice views 1/3
            self._shares_applied = True
            self._apply_splitter_shares()

    def _toggle_slice_column(self, shown: bool) -> None:
        if self.enlarged is not None:
            self.toggle_enlarged(self.enlarged)
        self.slice_column.setVisible(bool(shown))

    # -- views in the grid -------------------------------------------------------------------------------------
    def _apply_layout(self, layout: str) -> None:
        rows, columns = LAYOUTS[layout]
        if self.enlarged is not None and self.enlarged in self.views and self.enlarged.index >= rows * columns:
            self.enlarged = None
        for view in self.views:
            self.grid.removeWidget(view)
        for index, view in enumerate(self.views):
            visible = index < rows * columns
            if visible:
                self.grid.addWidget(view, index // columns, index % columns)
                if self.model.item is not None and (view.item is not self.model.item
                                                    or view.mode != self.model.view_modes[index]):
                    self._show_in(view)
            view.setVisible(visible and (self.enlarged is None or self.enlarged is view))
        if layout in getattr(self, "layout_actions", {}):
            self.layout_actions[layout].setChecked(True)

    def save_default_views(self) -> None:
        """View > Use these views as the default: the layout and each view's mode become what the next start shows.
        Only this writes them (a preference, not a side effect: ``voxelscope gui --modes`` or a session opened today
        does not change tomorrow's start)."""
        self.settings.setValue("layout", self.model.layout)
        self.settings.setValue("modes", ",".join(self.model.view_modes))
        self.settings.sync()
        self.statusBar().showMessage(f"New windows will start with {self.model.layout}: "
                                     + ", ".join(self.model.view_modes[: self.model.view_count]), 10000)

    def _active_widget(self):
        """The view the user worked in last (a 3D view, or a slice view that has the focus)."""
        for view in self.slice_views.values():
            if view.hasFocus():
                return view
        return self.views[self.active_view]

    def toggle_enlarged(self, view) -> None:
        """Show ``view`` (a 3D or slice view) alone in the central area, or go back to the layout."""
        rows, columns = LAYOUTS[self.model.layout]
        if self.enlarged is None:
            self.enlarged = view
            is_slice = view in self.slice_views.values()
            self.grid_widget.setVisible(not is_slice)
            self.slice_column.setVisible(is_slice)
            for other in self.views[: rows * columns]:
                other.setVisible(other is view)
            for other in self.slice_views.values():
                other.setVisible(other is view)
        else:
            self.enlarged = None
            self.grid_widget.setVisible(True)
            self.slice_column.setVisible(self.slices_action.isChecked())
            for index, other in enumerate(self.views):
                other.setVisible(index < rows * columns)
            for other in self.slice_views.values():
                other.setVisible(True)
        for other in self.views[: rows * columns]:
            if other.isVisible() and other.item is not None:
                other.camera_moved()  # a new size: software renderers draw a new frame once it settles
