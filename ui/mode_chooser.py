"""The render-mode chooser of a view: the modes that can show the view's item, grouped (surfaces, volume rendering,
comparisons...), each with its plain name, whose implementation it is, and its one-line description as tooltip."""

from __future__ import annotations

from qtpy.QtCore import Signal
from qtpy.QtWidgets import QComboBox

from app.modes import modes, modes_for

from .combo_rows import Row, fill


class ModeChooser(QComboBox):
    """A combo box of modes under group headings; ``mode_activated(name)`` when the user picks one."""

    mode_activated = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
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
        rows, group = [], None
        for mode in choices:
            if mode.group != group:
                group = mode.group
                rows.append(Row(group, heading=True))
            rows.append(Row(f"   {mode.label} ({mode.origin})", mode.name, f"{mode.name}: {mode.description}"))
        fill(self, rows)

    def _activated(self, index: int) -> None:
        name = self.itemData(index)
        if name:
            self.mode_activated.emit(name)
