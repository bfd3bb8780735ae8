"""The control panel: volume facts, isovalue with histogram, transfer function (preset and curve), shading,
window/level with presets for the volume's modality, slice interpolation and label opacity, and the view layout.
Every control writes through the :class:`app.workbench.WorkbenchModel`'s setters and follows its signals; nothing
is computed here. Presets made for another modality (CT presets on MR data) are listed apart and, when chosen
anyway, applied with a visible warning."""

from __future__ import annotations

from qtpy.QtCore import Qt, Signal
from qtpy.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QRadioButton,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from app.pipeline import STANDARD_VIEWS
from app.transfer import PRESETS
from app.workbench import CT_WINDOWS, INTERPOLATIONS, LAYOUTS, WorkbenchModel, presets_for, window_presets

from .curves import HistogramWidget, TransferFunctionEditor

SLIDER_STEPS = 1000
__all__ = ["ControlPanel", "CT_WINDOWS"]


class ControlPanel(QWidget):
    """All shared controls, bound to a :class:`WorkbenchModel`."""

    iso_preview = Signal(float)  # the isovalue while it is being dragged (surfaces show a preview)
    reset_camera = Signal(str)  # standard view name

    def __init__(self, model: WorkbenchModel, parent=None) -> None:
        super().__init__(parent)
        self.model = model
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 4, 4, 4)

        # Volume facts
        info_box = QGroupBox("Volume")
        self.info = QLabel("No volume")
        self.info.setObjectName("volume-info")
        self.info.setWordWrap(True)
        self.info.setTextInteractionFlags(Qt.TextSelectableByMouse)
        QVBoxLayout(info_box).addWidget(self.info)
        layout.addWidget(info_box)

        # Isovalue
        iso_box = QGroupBox("Isosurface")
        iso_layout = QVBoxLayout(iso_box)
        self.histogram = HistogramWidget()
        self.iso_slider = QSlider(Qt.Horizontal)
        self.iso_slider.setRange(0, SLIDER_STEPS)
        self.iso_slider.setObjectName("iso-slider")
        self.iso_spin = QDoubleSpinBox()
        self.iso_spin.setDecimals(1)
        self.iso_spin.setKeyboardTracking(False)
        self.iso_spin.setObjectName("iso-spin")
        row = QHBoxLayout()
        row.addWidget(self.iso_slider, 1)
        row.addWidget(self.iso_spin)
        iso_layout.addWidget(self.histogram)
        iso_layout.addLayout(row)
        layout.addWidget(iso_box)

        # Transfer function
        tf_box = QGroupBox("Transfer function")
        tf_layout = QVBoxLayout(tf_box)
        self.preset_box = QComboBox()
        self.preset_box.setObjectName("preset")
        self._fill_presets(list(PRESETS), [])
        self.preset_warning = QLabel("")
        self.preset_warning.setObjectName("preset-warning")
        self.preset_warning.setWordWrap(True)
        self.preset_warning.setStyleSheet("color: #e0a020;")
        self.preset_warning.hide()
        self.curve = TransferFunctionEditor()
        self.curve.setToolTip("Opacity: drag a point to move it, double-click to add one, right-click to remove one.\n"
                              "Colour: drag a marker under the colour bar, double-click it to choose its colour.")
        tf_layout.addWidget(self.preset_box)
        tf_layout.addWidget(self.preset_warning)
        tf_layout.addWidget(self.curve)
        layout.addWidget(tf_box)

        # Shading
        shading_box = QGroupBox("Shading")
        shading_layout = QFormLayout(shading_box)
        self.shading_check = QCheckBox("Blinn-Phong shading from gradients")
        shading_layout.addRow(self.shading_check)
        self.shading_sliders = {}
        for name in ("ambient", "diffuse", "specular"):
            slider = QSlider(Qt.Horizontal)
            slider.setRange(0, 100)
            slider.valueChanged.connect(lambda value, name=name: self._shading_term(name, value / 100.0))
            self.shading_sliders[name] = slider
            shading_layout.addRow(name.capitalize(), slider)
        layout.addWidget(shading_box)

        # Window / level
        wl_box = QGroupBox("Slices: window / level")
        wl_layout = QFormLayout(wl_box)
        self.window_spin = QDoubleSpinBox()
        self.level_spin = QDoubleSpinBox()
        for spin in (self.window_spin, self.level_spin):
            spin.setRange(-1e6, 1e6)
            spin.setDecimals(1)
            spin.setKeyboardTracking(False)
        self.window_spin.setMinimum(0.1)
        self.window_presets = QComboBox()
        self.window_presets.setObjectName("window-presets")
        self.window_presets.addItem("Presets...")
        wl_layout.addRow("Window", self.window_spin)
        wl_layout.addRow("Level", self.level_spin)
        wl_layout.addRow(self.window_presets)
        self.interpolation_box = QComboBox()
        self.interpolation_box.setObjectName("interpolation")
        for name in INTERPOLATIONS:
            self.interpolation_box.addItem(name, name)
        self.interpolation_box.setToolTip("How the slice views sample the volume (linear: trilinear)")
        wl_layout.addRow("Interpolation", self.interpolation_box)
        self.label_opacity = QSlider(Qt.Horizontal)
        self.label_opacity.setObjectName("label-opacity")
        self.label_opacity.setRange(0, 100)
        self.label_opacity.setValue(int(round(model.label_opacity * 100)))
        self.label_opacity.setToolTip("Opacity of label colours over the grey values")
        wl_layout.addRow("Label opacity", self.label_opacity)
        layout.addWidget(wl_box)

        # Views
        views_box = QGroupBox("Views")
        views_layout = QVBoxLayout(views_box)
        layout_row = QHBoxLayout()
        self.layout_buttons = QButtonGroup(self)
        for name in LAYOUTS:
            button = QRadioButton(name)
            button.setObjectName(f"layout-{name}")
            self.layout_buttons.addButton(button)
            layout_row.addWidget(button)
            button.toggled.connect(lambda checked, name=name: checked and self.model.set_layout(name))
        views_layout.addLayout(layout_row)
        self.link_check = QCheckBox("Link cameras")
        self.link_check.setObjectName("link-cameras")
        self.link_check.toggled.connect(self.model.set_cameras_linked)
        views_layout.addWidget(self.link_check)
        grid = QGridLayout()
        for position, name in enumerate(STANDARD_VIEWS):
            button = QPushButton(name.capitalize())
            button.setToolTip(f"Look at the patient from the {name} side")
            button.clicked.connect(lambda _=False, name=name: self.reset_camera.emit(name))
            grid.addWidget(button, position // 3, position % 3)
        views_layout.addLayout(grid)
        layout.addWidget(views_box)
        layout.addStretch(1)

        # Wiring: controls -> model
        self.iso_slider.sliderMoved.connect(lambda step: self._iso_moved(self._value_of(step)))
        self.iso_slider.sliderReleased.connect(lambda: self._iso_set(self._value_of(self.iso_slider.value())))
        self.iso_slider.valueChanged.connect(self._slider_stepped)
        self.iso_spin.valueChanged.connect(self._iso_set)
        self.histogram.iso_dragged.connect(self._iso_moved)
        self.histogram.iso_released.connect(self._iso_set)
        self.preset_box.activated.connect(self._preset_chosen)
        self.curve.points_changed.connect(self.model.set_opacity_points)
        self.curve.color_points_changed.connect(self.model.set_color_points)
        self.shading_check.toggled.connect(lambda on: self.model.set_shading(enabled=on))
        self.window_spin.valueChanged.connect(lambda w: self.model.set_window_level(w, self.model.level))
        self.level_spin.valueChanged.connect(lambda level: self.model.set_window_level(self.model.window, level))
        self.window_presets.activated.connect(self._window_preset)
        self.interpolation_box.activated.connect(
            lambda _: self.model.set_interpolation(self.interpolation_box.currentData()))
        self.label_opacity.valueChanged.connect(lambda value: self.model.set_label_opacity(value / 100.0))

        # Model -> controls
        model.item_changed.connect(self._item_changed)
        model.iso_changed.connect(self._iso_changed)
        model.transfer_function_changed.connect(self._transfer_function_changed)
        model.window_level_changed.connect(self._window_level_changed)
        model.layout_changed.connect(self._layout_changed)
        model.cameras_linked_changed.connect(self.link_check.setChecked)
        model.slice_display_changed.connect(self._display_changed)
        self._layout_changed(model.layout)
        self.link_check.setChecked(model.cameras_linked)
        self.setEnabled(False)

    # -- isovalue ----------------------------------------------------------------------------------------------
    def _value_of(self, step: int) -> float:
        lo, hi = self.model.require_volume().value_range
        return lo + (hi - lo) * step / SLIDER_STEPS

    def _step_of(self, value: float) -> int:
        lo, hi = self.model.require_volume().value_range
        return int(round((value - lo) / (hi - lo) * SLIDER_STEPS)) if hi > lo else 0

    def _iso_moved(self, value: float) -> None:
        self.histogram.set_iso(value)
        with _blocked(self.iso_spin):
            self.iso_spin.setValue(value)
        self.iso_preview.emit(value)

    def _iso_set(self, value: float) -> None:
        if self.model.volume is not None:
            self.model.set_iso(value)

    def _slider_stepped(self, step: int) -> None:
        if not self.iso_slider.isSliderDown():  # keyboard or page steps: apply directly
            self._iso_set(self._value_of(step))

    def _iso_changed(self, iso: float) -> None:
        self.histogram.set_iso(iso)
        with _blocked(self.iso_slider):
            self.iso_slider.setValue(self._step_of(iso))
        with _blocked(self.iso_spin):
            self.iso_spin.setValue(iso)

    # -- other model changes -------------------------------------------------------------------------------------
    def _item_changed(self, item) -> None:
        """The 3D views show a new item: its values set the isovalue's range and the histogram."""
        volume = getattr(item, "volume", None)
        if volume is not None:
            self._volume_changed(volume)

    def _volume_changed(self, volume) -> None:
        self.setEnabled(True)
        facts = volume.describe()
        lo, hi = volume.value_range
        source = volume.metadata.get("source_path", "")
        self.info.setText(
            f"<b>{source.split('/')[-1] or 'volume'}</b> ({facts['source_format']})<br>"
            f"{' x '.join(map(str, facts['dimensions']))} voxels<br>"
            f"{' x '.join(f'{s:g}' for s in facts['spacing'])} mm<br>"
            f"values {lo:g} to {hi:g} {volume.units_label}<br>"
            f"modality {volume.modality or 'unknown'}, axes {'/'.join(volume.axis_labels())}"
        )
        self.info.setToolTip(source)
        counts, edges = volume.histogram()
        self.histogram.set_histogram(counts, edges, volume.units_label)
        self.iso_spin.setSuffix(f" {volume.units_label}")
        with _blocked(self.iso_spin):
            self.iso_spin.setRange(lo, hi)
        for spin in (self.window_spin, self.level_spin):
            spin.setSuffix(f" {volume.units_label}")
        self.window_presets.clear()
        self.window_presets.addItem("Presets...")
        for name, (window, level) in window_presets(volume).items():
            self.window_presets.addItem(f"{name} ({window:g}/{level:g} {volume.units_label})", (window, level))
        suitable = presets_for(volume)
        self._fill_presets(suitable, [name for name in PRESETS if name not in suitable])
        self._iso_changed(self.model.iso)
        self._transfer_function_changed(self.model.transfer_function)
        self._window_level_changed(self.model.window, self.model.level)

    def _transfer_function_changed(self, function) -> None:
        volume = self.model.volume
        if volume is None or function is None:
            return
        position = self.preset_box.findData(self.model.preset)
        with _blocked(self.preset_box):
            self.preset_box.setCurrentIndex(max(position, 0))
        warning = self.model.preset_warning()
        self.preset_warning.setText(f"Warning: {warning}; colours and opacities may not fit these values."
                                    if warning else "")
        self.preset_warning.setVisible(bool(warning))
        self.curve.set_function(function, volume.value_range, volume.units_label)
        with _blocked(self.shading_check):
            self.shading_check.setChecked(function.shading.enabled)
        for name, slider in self.shading_sliders.items():
            with _blocked(slider):
                slider.setValue(int(round(getattr(function.shading, name) * 100)))
            slider.setEnabled(function.shading.enabled)

    def _fill_presets(self, suitable: list[str], others: list[str]) -> None:
        """The presets made for the volume's modality, then the others under a heading (chosen with a warning)."""
        from .combo_rows import Row, fill

        rows = [Row(name, name, PRESETS[name].description) for name in suitable]
        if others:
            rows.append(Row("Made for another modality:", heading=True))
            rows += [Row(f"   {name} (for {PRESETS[name].units or 'other'} values)", name,
                         PRESETS[name].description + " - not made for this volume's values",
                         roles={Qt.UserRole + 1: True}) for name in others]
        fill(self.preset_box, rows)

    def _preset_chosen(self, index: int) -> None:
        name = self.preset_box.itemData(index)
        if name:
            forced = bool(self.preset_box.itemData(index, Qt.UserRole + 1))
            self.model.set_preset(name, force=forced)

    def _shading_term(self, name: str, value: float) -> None:
        self.model.set_shading(**{name: value})

    def _display_changed(self) -> None:
        with _blocked(self.interpolation_box):
            self.interpolation_box.setCurrentIndex(max(self.interpolation_box.findData(self.model.interpolation), 0))
        with _blocked(self.label_opacity):
            self.label_opacity.setValue(int(round(self.model.label_opacity * 100)))

    def _window_level_changed(self, window: float, level: float) -> None:
        with _blocked(self.window_spin):
            self.window_spin.setValue(window)
        with _blocked(self.level_spin):
            self.level_spin.setValue(level)

    def _window_preset(self, index: int) -> None:
        data = self.window_presets.itemData(index)
        if data:
            self.model.set_window_level(*data)
        self.window_presets.setCurrentIndex(0)

    def _layout_changed(self, layout: str) -> None:
        for button in self.layout_buttons.buttons():
            if button.text() == layout:
                with _blocked(button):
                    button.setChecked(True)


class _blocked:
    """Silence a widget's signals while the panel mirrors the model into it."""

    def __init__(self, widget) -> None:
        self.widget = widget

    def __enter__(self):
        self.previous = self.widget.blockSignals(True)

    def __exit__(self, *exc):
        self.widget.blockSignals(self.previous)
