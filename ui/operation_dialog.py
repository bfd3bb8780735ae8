"""The dialog of an operation (Operations menu): one chooser per input, listing the scene's items of the kinds the
operation accepts, and the operation's options panel - both built from the operation's declarations."""

from __future__ import annotations

from typing import Any

from qtpy.QtWidgets import QComboBox, QDialog, QDialogButtonBox, QFormLayout, QLabel, QVBoxLayout

from .options_panel import OptionsPanel


class OperationDialog(QDialog):
    """Choose the inputs and options of an operation; :meth:`ask` returns ``(items, options)`` or None."""

    def __init__(self, operation, scene, parent=None, *, preferred=None) -> None:
        super().__init__(parent)
        self.setWindowTitle(operation.label)
        self.setObjectName(f"operation-{operation.name}")
        self.operation = operation
        layout = QVBoxLayout(self)
        description = QLabel(operation.description)
        description.setWordWrap(True)
        layout.addWidget(description)
        form = QFormLayout()
        self.inputs: dict[str, QComboBox] = {}
        for spec in operation.inputs:
            box = QComboBox()
            box.setObjectName(f"input-{spec.name}")
            if spec.optional:
                box.addItem("(none)", None)
            for item in scene:
                if spec.accepts(item):
                    box.addItem(f"{item.name} ({item.kind})", item.name)
            if preferred is not None and spec.accepts(preferred):
                box.setCurrentIndex(max(box.findData(preferred.name), 0))
            box.setToolTip(spec.help)
            self.inputs[spec.name] = box
            form.addRow(spec.name.replace("_", " ").capitalize(), box)
        layout.addLayout(form)
        self.options_panel = OptionsPanel(self)
        self.options_panel.set_mode(operation, operation.resolve_options())
        layout.addWidget(self.options_panel)
        buttons = QDialogButtonBox(QDialogButtonBox.Ok | QDialogButtonBox.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        self.ok_button = buttons.button(QDialogButtonBox.Ok)
        self.ok_button.setEnabled(all(box.count() for box in self.inputs.values()))  # every input can be given
        layout.addWidget(buttons)

    def chosen(self, scene) -> tuple[dict[str, Any], dict[str, Any]]:
        items = {name: scene.get(box.currentData()) if box.currentData() is not None else None
                 for name, box in self.inputs.items()}
        options = {option.name: self.options_panel.value(option.name) for option in self.operation.options}
        return items, {k: v for k, v in options.items() if v is not None}

    @classmethod
    def ask(cls, operation, scene, parent=None, *, preferred=None):
        dialog = cls(operation, scene, parent, preferred=preferred)
        if dialog.exec() != QDialog.Accepted:
            return None
        return dialog.chosen(scene)
