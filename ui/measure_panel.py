"""The Measurements panel: every distance, angle and region statistic of the session in a table (value with its
unit, mean/SD/min/max in the volume's units, where it was made), with Delete and Export CSV. The numbers come from
:mod:`app.measurements`; this panel only lists them."""

from __future__ import annotations

from qtpy.QtCore import Signal
from qtpy.QtWidgets import QPushButton, QTableWidget, QTableWidgetItem, QWidget

from .panel_layout import panel_layout, refresh_on

COLUMNS = ("Name", "Value", "Mean", "SD", "Min", "Max", "Where")


def _number(value, digits: int = 2) -> str:
    return "" if value is None else f"{value:.{digits}f}"


class MeasurementsPanel(QWidget):
    """``delete_requested(measurement)`` and ``export_requested()`` go to the window."""

    delete_requested = Signal(object)
    export_requested = Signal()

    def __init__(self, measurements, parent=None) -> None:
        super().__init__(parent)
        self.measurements = measurements
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setObjectName("measurements")
        self.table.setHorizontalHeaderLabels(COLUMNS)
        self.table.setEditTriggers(QTableWidget.NoEditTriggers)
        self.table.setSelectionBehavior(QTableWidget.SelectRows)
        self.table.verticalHeader().hide()
        self.delete_button = QPushButton("Delete")
        self.delete_button.clicked.connect(self._delete_current)
        self.export_button = QPushButton("Export CSV...")
        self.export_button.clicked.connect(self.export_requested.emit)
        panel_layout(self, self.table, (self.delete_button, self.export_button))
        refresh_on((measurements.added, measurements.removed, measurements.reset), self.refresh)

    def refresh(self) -> None:
        rows = list(self.measurements)
        self.table.setRowCount(len(rows))
        for row, measurement in enumerate(rows):
            r = measurement.results
            units = r.get("value_units", "")
            cells = (measurement.name, f"{_number(r.get('value'))} {r.get('unit', '')}",
                     _number(r.get("mean"), 1), _number(r.get("sd"), 1), _number(r.get("min"), 1),
                     _number(r.get("max"), 1), (measurement.plane or measurement.mask)
                     + (f" ({units})" if units else ""))
            for column, text in enumerate(cells):
                item = QTableWidgetItem(text)
                item.setToolTip(measurement.summary())
                self.table.setItem(row, column, item)
        self.table.resizeColumnsToContents()
        self.export_button.setEnabled(bool(rows))

    def _delete_current(self) -> None:
        row = self.table.currentRow()
        if 0 <= row < len(self.measurements):
            self.delete_requested.emit(self.measurements[row])
