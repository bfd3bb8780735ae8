"""A view's options panel: one widget per option of the view's render mode, built from the mode's typed options
(the same declarations the command line turns into flags). Options whose default is "automatic" offer that as
their first value."""

from __future__ import annotations

from typing import Any

from qtpy.QtCore import Signal
from qtpy.QtWidgets import QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout, QFrame, QLineEdit, QSpinBox

AUTOMATIC = "automatic"


class OptionsPanel(QFrame):
    """``changed({name: value})`` when the user edits an option; :meth:`set_values` updates without emitting."""

    changed = Signal(object)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("options-panel")
        self.setFrameShape(QFrame.StyledPanel)
        self.form = QFormLayout(self)
        self.form.setContentsMargins(6, 4, 6, 4)
        self.widgets: dict[str, Any] = {}
        self.mode = None

    def set_mode(self, mode, values: dict[str, Any]) -> None:
        """Build the widgets of ``mode``'s options, showing ``values``."""
        while self.form.rowCount():
            self.form.removeRow(0)
        self.widgets = {}
        self.mode = mode
        for option in mode.options:
            widget = self._widget(option)
            widget.setToolTip(option.help)
            widget.setObjectName(f"option-{option.name}")
            self.widgets[option.name] = widget
            self.form.addRow(option.label, widget)
        self.set_values(values)

    def set_values(self, values: dict[str, Any]) -> None:
        for name, widget in self.widgets.items():
            blocked = widget.blockSignals(True)
            self._show(self.mode.option(name), widget, values.get(name))
            widget.blockSignals(blocked)

    def value(self, name: str) -> Any:
        return self._read(self.mode.option(name), self.widgets[name])

    # -- widgets by option type ------------------------------------------------------------------------------------
    def _widget(self, option):
        emit = lambda *_: self.changed.emit({option.name: self.value(option.name)})  # noqa: E731
        if option.choices is not None:
            widget = QComboBox()
            if option.default is None:
                widget.addItem(AUTOMATIC, None)
            for choice in option.allowed:
                widget.addItem(str(choice), choice)
            widget.activated.connect(emit)
        elif option.type == "str":
            widget = QLineEdit()
            widget.setPlaceholderText(AUTOMATIC if option.default is None else "")
            widget.editingFinished.connect(emit)
        elif option.type == "bool":
            widget = QCheckBox()
            widget.toggled.connect(emit)
        else:
            widget = QSpinBox() if option.type == "int" else QDoubleSpinBox()
            low = option.minimum if option.minimum is not None else -1e9
            high = option.maximum if option.maximum is not None else 1e9
            if option.type == "int":
                widget.setRange(int(low) - (1 if option.default is None else 0), int(min(high, 2**31 - 1)))
            else:
                widget.setDecimals(3)
                widget.setSingleStep(0.1)
                widget.setRange(low - (1 if option.default is None else 0), high)
            if option.default is None:
                widget.setSpecialValueText(AUTOMATIC)  # shown at the minimum, one below the allowed range
            if option.unit:
                widget.setSuffix(f" {option.unit}")
            widget.setKeyboardTracking(False)
            widget.valueChanged.connect(emit)
        return widget

    def _show(self, option, widget, value) -> None:
        if isinstance(widget, QComboBox):
            position = widget.findData(value)
            widget.setCurrentIndex(max(position, 0))
        elif isinstance(widget, QLineEdit):
            widget.setText("" if value is None else str(value))
        elif isinstance(widget, QCheckBox):
            widget.setChecked(bool(value))
        else:
            widget.setValue(widget.minimum() if value is None else value)

    def _read(self, option, widget):
        if isinstance(widget, QComboBox):
            return widget.currentData()
        if isinstance(widget, QLineEdit):
            return widget.text() or None
        if isinstance(widget, QCheckBox):
            return widget.isChecked()
        if option.default is None and widget.value() == widget.minimum():
            return None
        return widget.value()
