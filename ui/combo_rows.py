"""Filling a combo box with grouped rows - entries and unselectable headings - through the combo's own model.

No ``QStandardItem`` is made in Python: an item made in Python and handed to a model has a Python wrapper that
PySide releases when the model deletes the item, and that release crashed the window (a segmentation fault in
``Shiboken::BindingManager::releaseWrapper`` from ``QStandardItemModel::~QStandardItemModel``, while a closed
window's widgets were deleted; caught by ``scripts/stress-gui`` with its native stacks). Rows added with
``QComboBox.addItem`` and shaped with ``setItemData`` live in C++ only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from qtpy.QtCore import Qt
from qtpy.QtWidgets import QComboBox

#: The role under which Qt's standard item model keeps an item's flags (``Qt::UserRole - 1``): 0 makes a row
#: that cannot be selected or enabled - a heading.
_FLAGS_ROLE = int(Qt.UserRole) - 1


@dataclass(frozen=True)
class Row:
    """One row: ``text`` shown, ``data`` (``Qt.UserRole``; None for a heading), a tooltip, and more roles."""

    text: str
    data: Any = None
    tooltip: str = ""
    heading: bool = False
    roles: dict = field(default_factory=dict)


def fill(combo: QComboBox, rows) -> None:
    """Replace the rows of ``combo`` (its signals blocked meanwhile); headings are bold and cannot be chosen."""
    blocked = combo.blockSignals(True)
    try:
        combo.clear()
        for row in rows:
            combo.addItem(row.text, row.data)
            index = combo.count() - 1
            if row.tooltip:
                combo.setItemData(index, row.tooltip, Qt.ToolTipRole)
            if row.heading:
                combo.setItemData(index, 0, _FLAGS_ROLE)
                font = combo.font()
                font.setBold(True)
                combo.setItemData(index, font, Qt.FontRole)
            for role, value in row.roles.items():
                combo.setItemData(index, value, role)
    finally:
        combo.blockSignals(blocked)
