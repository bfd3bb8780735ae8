"""The render-mode chooser of a view: the modes that can show the view's item, grouped (surfaces, volume rendering,
comparisons...), each with its plain name, whose implementation it is, and its one-line description as tooltip."""

from __future__ import annotations

from qtpy.QtCore import Qt, Signal
from qtpy.QtGui import QStandardItem, QStandardItemModel
from qtpy.QtWidgets import QComboBox

from app.modes import modes, modes_for


class ModeChooser(QComboBox):
    """A combo box of modes under group headings; ``mode_activated(name)`` when the user picks one."""

    mode_activated = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setModel(QStandardItemModel(self))
        # A bounded width: a view's header must not force a minimum window size; the list pops up wider.
        self.setSizeAdjustPolicy(QComboBox.AdjustToMinimumContentsLengthWithIcon)
        self.setMinimumContentsLength(14)
        self.view().setMinimumWidth(380)
        self.activated.connect(self._activated)
        self._fill(modes())

    def set_item(self, item) -> None:
        """List the modes that can show ``item`` (a scene item)."""
        current = self.currentData()
        self._fill(modes_for(item))
        if current is not None:
            self.set_current(current)

    def set_current(self, name: str) -> None:
        position = self.findData(name)
        if position >= 0:
            self.setCurrentIndex(position)

    def names(self) -> list[str]:
        return [self.itemData(i) for i in range(self.count()) if self.itemData(i)]

    def _fill(self, choices) -> None:
        model: QStandardItemModel = self.model()
        blocked = self.blockSignals(True)
        model.clear()
        group = None
        for mode in choices:
            if mode.group != group:
                group = mode.group
                heading = QStandardItem(group)
                heading.setFlags(Qt.NoItemFlags)
                font = heading.font()
                font.setBold(True)
                heading.setFont(font)
                model.appendRow(heading)
            entry = QStandardItem(f"   {mode.label} ({mode.origin})")
            entry.setData(mode.name, Qt.UserRole)
            entry.setToolTip(f"{mode.name}: {mode.description}")
            model.appendRow(entry)
        self.blockSignals(blocked)

    def _activated(self, index: int) -> None:
        name = self.itemData(index)
        if name:
            self.mode_activated.emit(name)
