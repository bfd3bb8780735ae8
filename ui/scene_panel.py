"""The scene panel: the items of the scene (volumes, fields, meshes, tetrahedral meshes) with what each is; the
chosen item is what the 3D views show, the others are drawn beside it (meshes) or over the slices (fields)."""

from __future__ import annotations

from qtpy.QtCore import Qt, Signal
from qtpy.QtWidgets import QListWidget, QListWidgetItem, QPushButton, QWidget

from .panel_layout import panel_layout, refresh_on

KIND_NAMES = {"volume": "volume", "field": "field", "mesh": "mesh", "tetmesh": "tetrahedra"}


class ScenePanel(QWidget):
    """A list of the scene's items; ``show_requested(name)`` and ``remove_requested(name)`` go to the model."""

    show_requested = Signal(str)
    remove_requested = Signal(str)

    def __init__(self, model, parent=None) -> None:
        super().__init__(parent)
        self.model = model
        self.list = QListWidget()
        self.list.setObjectName("scene-items")
        self.list.itemDoubleClicked.connect(lambda entry: self.show_requested.emit(entry.data(Qt.UserRole)))
        self.show_button = QPushButton("Show in views")
        self.show_button.clicked.connect(self._show_current)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self._remove_current)
        panel_layout(self, self.list, (self.show_button, self.remove_button))
        refresh_on((model.scene.item_added, model.scene.item_removed, model.scene.item_changed, model.item_changed),
                   self.refresh)

    def refresh(self) -> None:
        self.list.clear()
        for item in self.model.scene:
            role = f", {item.role}" if getattr(item, "role", None) else ""
            shown = " - shown" if item is self.model.item else ""
            entry = QListWidgetItem(f"{item.name} ({KIND_NAMES.get(item.kind, item.kind)}{role}){shown}")
            entry.setData(Qt.UserRole, item.name)
            self.list.addItem(entry)

    def _current(self) -> str | None:
        entry = self.list.currentItem()
        return entry.data(Qt.UserRole) if entry is not None else None

    def _show_current(self) -> None:
        name = self._current()
        if name:
            self.show_requested.emit(name)

    def _remove_current(self) -> None:
        name = self._current()
        if name:
            self.remove_requested.emit(name)
