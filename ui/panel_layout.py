"""The layout the dock panels share: their main widget (a list, a table, a text) taking the height, what belongs to
it underneath (a row of buttons, a form), 4 px margins; and a panel's refresh tied to the model signals it draws."""

from __future__ import annotations

from typing import Callable, Iterable

from qtpy.QtWidgets import QHBoxLayout, QLayout, QVBoxLayout, QWidget


def panel_layout(panel: QWidget, main: QWidget, *below, stretch: int = 1) -> QVBoxLayout:
    """Lay ``panel`` out as ``main`` over ``below``: each a widget, a layout, or a sequence of buttons (one row).
    ``stretch``: how ``main`` takes the panel's height (0: no more than it asks for)."""
    layout = QVBoxLayout(panel)
    layout.setContentsMargins(4, 4, 4, 4)
    layout.addWidget(main, stretch)
    for part in below:
        if isinstance(part, QLayout):
            layout.addLayout(part)
        elif isinstance(part, QWidget):
            layout.addWidget(part)
        else:
            row = QHBoxLayout()
            for button in part:
                row.addWidget(button)
            layout.addLayout(row)
    return layout


def refresh_on(signals: Iterable, refresh: Callable[[], None]) -> None:
    """Call ``refresh()`` now and whenever one of the model's ``signals`` fires (whatever it carries)."""
    for signal in signals:
        signal.connect(lambda *_: refresh())
    refresh()
