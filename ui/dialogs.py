"""Small dialogs: DICOM series chooser and mesh export options."""

from __future__ import annotations

from qtpy.QtCore import Qt
from qtpy.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFormLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QSpinBox,
    QVBoxLayout,
)

from app.mesh_cleanup import Cleanup


class SeriesChooser(QDialog):
    """Pick one of several image series found in a DICOM folder (largest first, preselected)."""

    def __init__(self, folder: str, series: list[dict], parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Choose a DICOM series")
        layout = QVBoxLayout(self)
        layout.addWidget(QLabel(f"{folder} holds {len(series)} image series. Which one should be opened?"))
        self.list = QListWidget()
        first = None
        for item in series:
            text = (f"{item['description'] or 'no description'}  |  {item['modality'] or '?'}  |  "
                    f"{item['slices']} images of {item['columns']}x{item['rows']}  |  {item['series_uid']}")
            entry = QListWidgetItem(text)
            entry.setData(256, item["series_uid"])
            if not item.get("loadable", True):  # shown, greyed out, with the reason it cannot be opened
                entry.setText(f"{text}\n      cannot be opened: {item['reason']}")
                entry.setFlags(entry.flags() & ~Qt.ItemIsEnabled & ~Qt.ItemIsSelectable)
                entry.setToolTip(item["reason"])
            elif first is None:
                first = self.list.count()
            self.list.addItem(entry)
        self.list.setCurrentRow(first if first is not None else -1)
        self.list.itemDoubleClicked.connect(lambda _: self.accept())
        layout.addWidget(self.list)
        buttons = QDialogButtonBox(QDialogButtonBox.Open | QDialogButtonBox.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)

    def chosen_uid(self) -> str | None:
        item = self.list.currentItem()
        return item.data(256) if item is not None else None

    @classmethod
    def ask(cls, folder: str, series: list[dict], parent=None) -> str | None:
        dialog = cls(folder, series, parent)
        return dialog.chosen_uid() if dialog.exec() == QDialog.Accepted else None


class ExportOptionsDialog(QDialog):
    """Coordinate system and clean-up options of a mesh export (see :func:`app.meshing.export_mesh`)."""

    def __init__(self, path: str, parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Export mesh")
        form = QFormLayout(self)
        form.addRow(QLabel(f"Writing {path}"))
        self.coordinates = QComboBox()
        self.coordinates.addItem("LPS mm (DICOM, ITK, 3D Slicer)", "LPS")
        self.coordinates.addItem("RAS mm (NIfTI, FreeSurfer, most 3D printing tools)", "RAS")
        form.addRow("Coordinates", self.coordinates)
        self.smooth = QSpinBox()
        self.smooth.setRange(0, 500)
        self.smooth.setSpecialValueText("off")
        self.smooth.setToolTip("Windowed-sinc smoothing iterations")
        form.addRow("Smoothing iterations", self.smooth)
        self.decimate = QDoubleSpinBox()
        self.decimate.setRange(0.0, 0.95)
        self.decimate.setSingleStep(0.05)
        self.decimate.setSpecialValueText("off")
        self.decimate.setToolTip("Fraction of triangles removed by quadric decimation")
        form.addRow("Decimation", self.decimate)
        self.largest = QCheckBox("Keep the largest connected piece only")
        form.addRow(self.largest)
        self.fill_holes = QDoubleSpinBox()
        self.fill_holes.setRange(0.0, 100.0)
        self.fill_holes.setSuffix(" mm")
        self.fill_holes.setSpecialValueText("off")
        form.addRow("Close holes up to", self.fill_holes)
        self.close_edges = QCheckBox("Cap the surface where it leaves the volume")
        self.close_edges.setToolTip("Extracts the surface again from the volume padded by one voxel of air, so a "
                                    "skull cut by the last slice is closed there (for 3D printing)")
        form.addRow(self.close_edges)
        buttons = QDialogButtonBox(QDialogButtonBox.Save | QDialogButtonBox.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def options(self) -> dict:
        cleanup = Cleanup(smooth_iterations=self.smooth.value(), decimate=self.decimate.value(),
                          largest_component=self.largest.isChecked(), fill_holes_mm=self.fill_holes.value())
        return {"coordinates": self.coordinates.currentData(), "cleanup": cleanup,
                "close_edges": self.close_edges.isChecked()}

    @classmethod
    def ask(cls, path: str, parent=None) -> dict | None:
        dialog = cls(path, parent)
        return dialog.options() if dialog.exec() == QDialog.Accepted else None
