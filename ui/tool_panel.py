"""The cut-away tool list of the control area: add (box, sphere, plane), remove, show/hide, mode (remove/keep) of
the selected tool, and the evaluation (binary/distance) of all. Widgets only: every change is a signal the window
turns into a change of the shared :class:`app.cutaways.Cutaways`."""

from __future__ import annotations

from qtpy.QtCore import Qt, Signal
from qtpy.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGridLayout,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QWidget,
)

from app.cutaways import CUT_EVALUATIONS, CUT_MODES

from .panel_layout import panel_layout


def tool_label(tool) -> str:
    """One line for the list: shape, mode and where it is (LPS mm)."""
    centre = ", ".join(f"{v:.0f}" for v in tool.centre)
    return f"{tool.shape} ({tool.mode}) at {centre} mm"


class ToolPanel(QWidget):
    """The tool list. ``add_requested(shape)``, ``remove_requested(index)``, ``visibility_changed(index, on)``,
    ``mode_changed(index, mode)``, ``evaluation_changed(evaluation)``, ``current_changed(index)``."""

    add_requested = Signal(str)
    remove_requested = Signal(int)
    visibility_changed = Signal(int, bool)
    mode_changed = Signal(int, str)
    evaluation_changed = Signal(str)
    current_changed = Signal(int)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("tool-panel")
        self.list = QListWidget()
        self.list.setObjectName("tool-list")
        self.list.setToolTip("Cut-away tools (source 002's selection volumes); the selected one has a widget in "
                             "every 3D view. Untick to hide a tool.")
        self.list.currentRowChanged.connect(self._row_changed)
        self.list.itemChanged.connect(self._item_changed)
        buttons = QGridLayout()  # two by two: the dock stays as narrow as its neighbours
        self.add_buttons = {}
        for index, shape in enumerate(("box", "sphere", "plane")):
            button = QPushButton(f"Add {shape}")
            button.setObjectName(f"add-{shape}")
            button.clicked.connect(lambda _=False, shape=shape: self.add_requested.emit(shape))
            buttons.addWidget(button, index // 2, index % 2)
            self.add_buttons[shape] = button
        self.remove_button = QPushButton("Remove")
        self.remove_button.setObjectName("remove-tool")
        self.remove_button.clicked.connect(lambda: self._emit_for_current(self.remove_requested.emit))
        buttons.addWidget(self.remove_button, 1, 1)
        self.mode_box = QComboBox()
        self.mode_box.setObjectName("tool-mode")
        self.mode_box.addItems(list(CUT_MODES))
        self.mode_box.setToolTip("remove: cut away what is inside; keep: keep only the inside (a region of "
                                 "interest, exported by File > Export cropped volume)")
        self.mode_box.activated.connect(
            lambda _: self._emit_for_current(lambda row: self.mode_changed.emit(row, self.mode_box.currentText())))
        self.evaluation_box = QComboBox()
        self.evaluation_box.setObjectName("tool-evaluation")
        self.evaluation_box.addItems(list(CUT_EVALUATIONS))
        self.evaluation_box.setToolTip("binary: source 002's per-sample test; distance: the difference of distance "
                                       "fields, a smooth cut shaded with the tool's normal")
        self.evaluation_box.activated.connect(lambda _: self.evaluation_changed.emit(self.evaluation_box.currentText()))
        form = QFormLayout()
        form.addRow("Mode", self.mode_box)
        form.addRow("Evaluation", self.evaluation_box)
        panel_layout(self, self.list, buttons, form, stretch=0)
        self._updating = False

    def show_tools(self, tools, evaluation: str, current: int) -> None:
        """List ``tools`` with ``current`` selected (no signals)."""
        self._updating = True
        try:
            self.list.clear()
            for tool in tools:
                item = QListWidgetItem(tool_label(tool))
                item.setFlags(item.flags() | Qt.ItemIsUserCheckable)
                item.setCheckState(Qt.Checked if tool.visible else Qt.Unchecked)
                self.list.addItem(item)
            self.list.setCurrentRow(current if 0 <= current < len(tools) else -1)
            if 0 <= current < len(tools):
                self.mode_box.setCurrentText(tools[current].mode)
            self.evaluation_box.setCurrentText(evaluation)
            self.remove_button.setEnabled(bool(tools))
            self.mode_box.setEnabled(bool(tools))
        finally:
            self._updating = False

    def _emit_for_current(self, emit) -> None:
        row = self.list.currentRow()
        if row >= 0:
            emit(row)

    def _row_changed(self, row: int) -> None:
        if not self._updating and row >= 0:
            self.current_changed.emit(row)

    def _item_changed(self, item) -> None:
        if not self._updating:
            self.visibility_changed.emit(self.list.row(item), item.checkState() == Qt.Checked)
