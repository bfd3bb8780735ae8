"""The workbench window's tools: undo/redo (Qt's undo stack over the model's changes), the measuring tools
(distance, angle, ellipse statistics in slice views; distance and angle by picking in 3D views; statistics inside a
mask), the Measurements and Provenance panels, and the label-volume actions (open, colour table, one mesh per
label). A mixin of :class:`ui.main_window.MainWindow`; every number comes from ``app``."""

from __future__ import annotations

from pathlib import Path

from qtpy.QtCore import Qt
from qtpy.QtGui import QAction, QActionGroup, QKeySequence
from qtpy.QtWidgets import QFileDialog, QInputDialog, QToolBar

from app.labels import export_label_meshes, read_color_table
from app.measurements import Measurement
from app.workbench import load_for_workbench

from .measure_panel import MeasurementsPanel
from .provenance_panel import ProvenancePanel
from .tasks import Task
from .undo import bind_undo_stack, close_merging

TOOL_LABELS = {"navigate": "Navigate", "distance": "Distance (mm)", "angle": "Angle (degrees)",
               "ellipse": "Ellipse statistics"}
TOOL_TIPS = {
    "navigate": "Left button: crosshair (Ctrl+drag rotates it), right: window/level, middle or Shift+left: pan, "
                "wheel: slices, Ctrl+wheel: zoom, double-click: one big view",
    "distance": "Drag from one point to the other in a slice view, or click two surface points in a 3D view",
    "angle": "Click three points (the vertex second) in a slice view or on a surface in a 3D view",
    "ellipse": "Drag the box of an ellipse in a slice view: mean, SD, minimum, maximum and area",
}


class ToolActions:
    def _build_tools(self) -> None:
        self.undo_stack = bind_undo_stack(self.model, self)
        self.undo_action = self.undo_stack.createUndoAction(self, "&Undo")
        self.undo_action.setShortcut(QKeySequence.Undo)
        self.redo_action = self.undo_stack.createRedoAction(self, "&Redo")
        self.redo_action.setShortcuts([QKeySequence.Redo, QKeySequence("Ctrl+Y")])

        self.tools_toolbar = QToolBar("Tools", self)
        self.tools_toolbar.setObjectName("tools")
        self.addToolBar(Qt.TopToolBarArea, self.tools_toolbar)
        group = QActionGroup(self)
        self.tool_actions: dict[str, QAction] = {}
        for name, text in TOOL_LABELS.items():
            action = QAction(text, self)
            action.setCheckable(True)
            action.setToolTip(TOOL_TIPS[name])
            action.setStatusTip(TOOL_TIPS[name])
            action.triggered.connect(lambda _=False, name=name: self.set_tool(name))
            group.addAction(action)
            self.tools_toolbar.addAction(action)
            self.tool_actions[name] = action
        self.tool_actions["navigate"].setChecked(True)
        self.tool = "navigate"
        self._picks: list = []

        self.measurements_panel = MeasurementsPanel(self.model.measurements)
        self.measurements_panel.delete_requested.connect(self.model.remove_measurement)
        self.measurements_panel.export_requested.connect(self.export_measurements_dialog)
        self.measurements_dock = self._dock("Measurements", "measurements", self.measurements_panel,
                                            Qt.RightDockWidgetArea)
        self.provenance_panel = ProvenancePanel()
        self.provenance_dock = self._dock("Provenance", "provenance", self.provenance_panel, Qt.RightDockWidgetArea)
        self.tabifyDockWidget(self.scene_dock, self.measurements_dock)
        self.tabifyDockWidget(self.measurements_dock, self.provenance_dock)
        self.scene_dock.raise_()

        for view in self.slice_views.values():
            view.measured.connect(self._measured)
            view.drag_finished.connect(lambda: close_merging(self.undo_stack))
        for view in self.views:
            view.point_picked.connect(self._picked_in_3d)
        for signal in (self.model.measurements.added, self.model.measurements.removed,
                       self.model.measurements.reset):
            signal.connect(lambda *_: self._measurements_changed())

    # -- measuring tools -------------------------------------------------------------------------------------
    def set_tool(self, tool: str) -> None:
        """Choose the mouse tool of every view: navigate, distance, angle or ellipse."""
        if tool not in TOOL_LABELS:
            raise ValueError(f"tool must be one of {', '.join(TOOL_LABELS)}, got {tool!r}")
        self.tool = tool
        self._picks = []
        self.tool_actions[tool].setChecked(True)
        for view in self.slice_views.values():
            view.set_tool(tool)
        for view in self.views:
            view.set_tool(tool if tool in ("distance", "angle") else "navigate")
        self.statusBar().showMessage(TOOL_TIPS[tool], 10000)

    def _measured(self, spec: dict) -> None:
        try:
            measurement = self.model.add_measurement(Measurement(**spec))
        except ValueError as exc:
            self._report_error(str(exc), "Measurement")
            return
        self.statusBar().showMessage(f"{measurement.name}: {measurement.summary()}", 30000)

    def _picked_in_3d(self, point) -> None:
        needed = {"distance": 2, "angle": 3}.get(self.tool)
        if needed is None:
            return
        self._picks.append([float(c) for c in point])
        if len(self._picks) < needed:
            self.statusBar().showMessage(f"Point {len(self._picks)} of {needed} at "
                                         f"({', '.join(f'{c:.1f}' for c in point)}) mm LPS", 10000)
            return
        points, self._picks = self._picks, []
        self._measured({"kind": self.tool, "points": points, "plane": "3d"})

    def _measurements_changed(self) -> None:
        measurements = list(self.model.measurements)
        for view in self.slice_views.values():
            view.set_measurements(measurements)
        polylines = [m.points for m in measurements if m.radii is None and len(m.points) >= 2]
        for view in self.views:
            view.set_measurements(polylines)

    def export_measurements_dialog(self) -> None:
        if not len(self.model.measurements):
            self._report_error("There are no measurements to export yet.", "Nothing to export")
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export measurements", self._last_folder(), "CSV (*.csv)")
        if not path:
            return
        path = Path(path) if path.lower().endswith(".csv") else Path(path + ".csv")
        try:
            self.model.measurements.write_csv(path, overwrite=path.exists())  # the dialog asked before replacing
        except (OSError, ValueError) as exc:
            self._report_error(f"Could not write {path}:\n\n{exc}")
            return
        self.statusBar().showMessage(f"Wrote {len(self.model.measurements)} measurements to {path}", 15000)

    def mask_statistics_dialog(self) -> None:
        masks = [item.name for item in self.model.scene.of_kind("field") if item.role == "mask"]
        if not masks or self.model.base_volume is None:
            self._report_error("Statistics inside a mask need a volume and a mask in the scene (make one with a "
                               "cut-away tool or an operation first).", "No mask")
            return
        name, ok = QInputDialog.getItem(self, "Statistics inside a mask", "Mask", masks, 0, False)
        if ok:
            self._measured({"kind": "mask", "mask": name, "points": []})

    # -- label volumes -----------------------------------------------------------------------------------------
    def open_labels_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open label volume", self._last_folder(),
                                              "Volumes (*.nii *.nii.gz *.nrrd *.nhdr *.mha *.mhd *.vti *.img *.hdr);;"
                                              "All files (*)")
        if path:
            self.open_labels(path)

    def open_labels(self, path, color_table=None) -> None:
        """Load a label volume in a worker and draw it over the volume on show (or show it alone)."""
        path = Path(path)
        task = Task(f"Loading labels {path.name}", load_for_workbench, path, labels=True, color_table=color_table)
        task.finished.connect(lambda volume: self._labels_loaded(path, volume))
        task.failed.connect(lambda exc: self._load_error(path, exc))
        self.tasks.start(task)

    def _labels_loaded(self, path: Path, volume) -> None:
        item = self.model.add_labels(volume, path.name)
        table = volume.metadata["label_table"]
        named = sum(1 for entry in table.entries.values() if entry.name)
        self.statusBar().showMessage(f"Opened labels {item.name}: {named} named labels"
                                     + (f" from {', '.join(Path(s).name for s in table.sources)}"
                                        if table.sources else ", generated colours"), 15000)
        self.volume_loaded.emit(volume)

    def _label_volumes(self) -> list:
        items = list(self.model.label_items)
        if self.model.base is not None and "label_table" in self.model.base.volume.metadata:
            items.insert(0, self.model.base)
        return items

    def load_color_table_dialog(self) -> None:
        items = self._label_volumes()
        if not items:
            self._report_error("Open a label volume first (File > Open label volume).", "No labels")
            return
        path, _ = QFileDialog.getOpenFileName(self, "Load colour table", self._last_folder(),
                                              "Colour tables (*.txt *.ctbl *.lut *.label *.csv);;All files (*)")
        if path:
            self.apply_color_table(path, items[-1])

    def apply_color_table(self, path, item) -> None:
        try:
            table = read_color_table(path)
        except ValueError as exc:
            self._report_error(str(exc), "Colour table")
            return
        for holder in (item.metadata, item.volume.metadata):
            holder["label_table"] = table.merged(holder.get("label_table") or table)
        self._overlay_cache.clear()
        self._update_slice_overlays()
        if item is self.model.base:
            self._volume_changed(item.volume)

    def export_label_meshes_dialog(self) -> None:
        items = self._label_volumes()
        if not items:
            self._report_error("Open a label volume first (File > Open label volume).", "No labels")
            return
        folder = QFileDialog.getExistingDirectory(self, "Folder for one mesh per label", self._last_folder())
        if not folder:
            return
        self.export_label_meshes(items[-1], folder)

    def export_label_meshes(self, item, folder, *, labels="all", overwrite: bool = False) -> Task:
        """Write one closed mesh per label of ``item`` into ``folder`` (what ``voxelscope mesh --labels`` does)."""
        volume = item.volume
        task = Task(f"Meshes of {item.name}", export_label_meshes, volume, folder, labels=labels,
                    table=volume.metadata.get("label_table"), overwrite=overwrite)
        task.finished.connect(lambda listing: self.statusBar().showMessage(
            f"Wrote {len(listing['meshes'])} label meshes and labels.json to {folder}", 15000))
        task.failed.connect(lambda exc: self._report_error(f"Could not write the label meshes:\n\n{exc}",
                                                           "Export failed"))
        return self.tasks.start(task)
