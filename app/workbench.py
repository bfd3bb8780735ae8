"""The workbench's state, without Qt: the scene (volumes, fields, meshes, label maps...), the item the views show,
the isovalue, the transfer function, window/level, the layout of views, each view's render mode and options, camera
linking, the slice cursor with its oblique rotation and interpolation, label display, the measurements and the
cut-away tools.

Widgets in ``ui`` subscribe to the signals and write back through the setters; tests and scripts drive the same
object headless. Setters validate their input (ValueError with a clear message) and emit only on real changes.

Undo: every edit a user may want to take back (isovalue, transfer function and preset, shading, slice rotation,
measurements added or removed) is announced by ``undoable(change)`` with a :class:`Change` that can restore the
state before and after it; the window puts these on Qt's undo stack. ``history_cleared`` says a new item was shown
(old changes no longer apply).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from algorithms.common.progress import scaled

from .cutaways import Cutaways
from .events import Signal
from .io import load_volume
from .io.meshes import is_mesh_path, load_mesh
from .labels import as_labels, is_label_map, table_for
from .measurements import Measurement, MeasurementList
from .modes import get_mode, modes_for
from .scene import FieldItem, MeshItem, Scene, VolumeItem
from .slices import PLANES, plane_frame, rotation_about
from .transfer import PRESETS, Shading, TransferFunction, default_preset_name, transfer_function_for
from .volume import Volume, default_iso

LAYOUTS = {"1x1": (1, 1), "1x2": (1, 2), "2x2": (2, 2)}
DEFAULT_MODES = ("flying-edges", "vtk-gpu", "vtk-marching-cubes", "vtk-cpu")
MESH_MODE = "mesh"
MAX_VIEWS = 4
INTERPOLATIONS = ("linear", "nearest")
CT_WINDOWS = {  # name -> (window, level) in HU
    "Soft tissue": (400.0, 40.0),
    "Brain": (80.0, 40.0),
    "Bone": (1800.0, 400.0),
    "Lung": (1500.0, -600.0),
}


def default_window_level(volume: Volume) -> tuple[float, float]:
    """A first window/level: the soft-tissue window (400/40 HU) for CT, the robust value range otherwise."""
    if volume.units == "HU":
        return 400.0, 40.0
    lo, hi = volume.percentile_range(0.5, 99.5)
    return hi - lo, 0.5 * (lo + hi)


def window_presets(volume: Volume) -> dict[str, tuple[float, float]]:
    """Window/level presets for the volume's modality: the HU windows for CT; for MR and other data, automatic
    windows from the volume's own values (robust 0.5-99.5 % and 2-98 % ranges, and the full range)."""
    if volume.units == "HU":
        return dict(CT_WINDOWS)
    presets = {}
    for name, (low, high) in (("Automatic (0.5-99.5 %)", (0.5, 99.5)), ("High contrast (2-98 %)", (2.0, 98.0))):
        lo, hi = volume.percentile_range(low, high)
        presets[name] = (hi - lo, 0.5 * (lo + hi))
    lo, hi = volume.value_range
    presets["Full range"] = (max(hi - lo, 1e-3), 0.5 * (lo + hi))
    return presets


def preset_suits(volume: Volume, name: str) -> bool:
    """A preset in absolute HU suits CT in HU only; presets relative to the value range suit any volume."""
    preset = PRESETS[name]
    return not preset.units or preset.units == volume.units


def presets_for(volume: Volume) -> list[str]:
    """The transfer-function presets made for the volume's modality (CT presets for CT in HU only)."""
    return [name for name in PRESETS if preset_suits(volume, name)]


@dataclass
class Change:
    """One undoable edit: ``undo()`` restores the state before it, ``redo()`` the state after it."""

    label: str
    undo: Callable[[], None]
    redo: Callable[[], None]
    merge_key: str = ""  # consecutive changes with the same key (one drag) may be merged into one undo step


def load_for_workbench(path, *, series_uid: str | None = None, labels: bool | None = None, color_table=None,
                       progress=None):
    """Read a volume or a mesh file off the GUI thread. For a volume, also compute what the workbench shows at once
    (value range, robust range, histogram; cached on the volume) and whether it is a label map (``labels``: force
    the answer; see :func:`mark_labels`). Returns a :class:`Volume` or a loaded mesh."""
    if is_mesh_path(path):
        return load_mesh(path)
    volume = load_volume(path, series_uid=series_uid, progress=scaled(progress, 0.0, 0.9))
    volume.value_range
    volume.percentile_range()
    volume.histogram()
    mark_labels(volume, labels, color_table)
    return volume


def mark_labels(volume: Volume, labels: bool | None = None, color_table=None) -> Volume:
    """Decide whether ``volume`` is a label map (``labels`` True/False, or None to detect it) and, if so, attach its
    :class:`app.labels.LabelTable` (``color_table``: a file, else the tables next to the volume) as
    ``metadata["label_table"]``."""
    if labels is None:
        labels = is_label_map(volume)
    if labels:
        stored = as_labels(volume)
        volume.array, volume.units = stored.array, stored.units
        volume.metadata["label_table"] = table_for(volume, color_table)
    return volume


class WorkbenchModel:
    """Everything the views and controls share. All coordinates are LPS mm; values are in the volume's units."""

    def __init__(self) -> None:
        self.item_changed = Signal()  # (item): the item the 3D views show is a new one
        self.volume_changed = Signal()  # (volume): a new base volume (slice views, cursor, window/level)
        self.iso_changed = Signal()  # (iso)
        self.transfer_function_changed = Signal()  # (transfer_function)
        self.window_level_changed = Signal()  # (window, level)
        self.layout_changed = Signal()  # (layout name)
        self.view_mode_changed = Signal()  # (index, mode name, options)
        self.view_options_changed = Signal()  # (index, options)
        self.cameras_linked_changed = Signal()  # (linked)
        self.cursor_changed = Signal()  # (point)
        self.slice_rotation_changed = Signal()  # (3x3 rotation)
        self.slice_display_changed = Signal()  # (): interpolation or label opacity
        self.undoable = Signal()  # (Change)
        self.history_cleared = Signal()  # ()
        self.notice = Signal()  # (text): something the user should read (a preset forced on the wrong modality)

        self.scene = Scene()
        self.item = None  # the scene item the 3D views show
        self.base = None  # the volume item the slice views show (fields are drawn over it)
        self.iso: float = 0.0
        self.preset: str = ""
        self.transfer_function: TransferFunction | None = None
        self.window: float = 1.0
        self.level: float = 0.0
        self.layout: str = "2x2"
        self.view_modes: list[str] = list(DEFAULT_MODES)
        self.view_options: list[dict[str, Any]] = [{} for _ in range(MAX_VIEWS)]
        self.cameras_linked: bool = True
        self.cursor: np.ndarray = np.zeros(3)
        self.slice_rotation: np.ndarray = np.eye(3)
        self.interpolation: str = "linear"
        self.label_opacity: float = 0.5
        self.measurements = MeasurementList()
        self.cutaways = Cutaways()  # the cut-away tools every 3D view honours (LPS mm)
        self._replaying = 0

    # -- items -------------------------------------------------------------------------------------------------------
    @property
    def volume(self) -> Volume | None:
        """The volume (or field) the 3D views show; None when they show a mesh or nothing."""
        return getattr(self.item, "volume", None)

    @property
    def base_volume(self) -> Volume | None:
        """The volume the slice views show (the last volume opened)."""
        return self.base.volume if self.base is not None else None

    def overlays(self) -> list:
        """The fields of the scene (masks, distance fields, labels), drawn over the base volume's slices."""
        return self.scene.of_kind("field")

    def set_volume(self, volume: Volume, name: str | None = None) -> VolumeItem:
        """Show a new volume (it replaces the volume on show): isovalue, preset, window/level and cursor are reset
        to its defaults. A label map (``metadata["label_table"]``, see :func:`mark_labels`) is drawn in its label
        colours in the slice views."""
        for old in self.scene.of_kind("volume"):
            self.scene.remove(old.name)
        self.base = None
        name = name or Path(volume.metadata.get("source_path", "") or "volume").name or "volume"
        item = self.scene.add(VolumeItem(name, volume=volume, metadata=dict(volume.metadata)))
        self.show_item(item)
        return item

    def add_labels(self, volume: Volume, name: str | None = None) -> FieldItem:
        """Add a label map over the volume on show (drawn in its colours over the slices, names on hover); with no
        volume on show it becomes the volume on show. ``volume.metadata["label_table"]`` gives names and colours
        (:func:`mark_labels` attaches it)."""
        if "label_table" not in volume.metadata:
            mark_labels(volume, True)
        if self.base is None:
            return self.set_volume(volume, name)
        name = name or Path(volume.metadata.get("source_path", "") or "labels").name or "labels"
        return self.scene.add(FieldItem(name, volume=volume, role="labels", metadata=dict(volume.metadata)))

    def open_volume(self, volume: Volume, name: str | None = None):
        """What File > Open does with a volume: a label map opened over an overlapping volume is added as labels
        over it; anything else replaces the volume on show."""
        if "label_table" in volume.metadata and self.base is not None and _overlap(self.base.volume, volume):
            return self.add_labels(volume, name)
        return self.set_volume(volume, name)

    @property
    def label_items(self) -> list:
        """The label maps drawn over the slices (fields of role ``labels``)."""
        return [item for item in self.scene.of_kind("field") if item.role == "labels"]

    def add_mesh(self, mesh, name: str | None = None) -> MeshItem:
        """Add a surface mesh (read by :func:`app.io.meshes.load_mesh`, or a :class:`MeshItem`; LPS mm) to the scene;
        it becomes the item on show when there is no volume."""
        item = self.scene.add(mesh if isinstance(mesh, MeshItem) else MeshItem.from_mesh(mesh, name))
        if self.volume is None:
            self.show_item(item)
        return item

    def show_item(self, item) -> None:
        """Make ``item`` (in the scene) the one the views show; views whose mode cannot show it switch to one that
        can."""
        if item.name not in self.scene:
            raise ValueError(f"{item.name} is not in the scene")
        self.item = item
        volume = self.volume
        new_base = item.kind == "volume"
        if volume is not None:
            self.iso = getattr(item, "iso", None) if item.kind == "field" else None
            if self.iso is None:
                self.iso = 0.5 if "label_table" in volume.metadata else default_iso(volume)
            self.preset = default_preset_name(volume)
            self.transfer_function = transfer_function_for(volume, self.preset)
        if new_base:
            self.base = item
            self.window, self.level = default_window_level(volume)
            self.cursor = volume.centre
            self.slice_rotation = np.eye(3)
            self.measurements.replace_all([])
        usable = {mode.name for mode in modes_for(item)}
        for index, mode in enumerate(self.view_modes):
            if mode not in usable:
                self.view_modes[index] = MESH_MODE if item.kind == "mesh" else DEFAULT_MODES[index]
                self.view_options[index] = {}
        self.history_cleared.emit()
        self.item_changed.emit(item)
        if new_base:
            self.volume_changed.emit(volume)

    def require_volume(self) -> Volume:
        """The volume the 3D views show (a ValueError when there is none)."""
        if self.volume is None:
            raise ValueError("no volume is open")
        return self.volume

    # -- isovalue ------------------------------------------------------------------------------------------------
    def set_iso(self, iso: float) -> None:
        volume = self.require_volume()
        iso = float(iso)
        if not np.isfinite(iso):
            raise ValueError(f"the isovalue must be a finite number, got {iso}")
        lo, hi = volume.value_range
        if not lo <= iso <= hi:
            raise ValueError(f"isovalue {iso:g} lies outside the volume's range {lo:g} to {hi:g} {volume.units_label}")
        if iso != self.iso:
            before = self.iso
            self.iso = iso
            self.iso_changed.emit(iso)
            self._record(f"Isovalue {before:g} -> {iso:g} {volume.units_label}", lambda: self.set_iso(before),
                         lambda: self.set_iso(iso))

    # -- transfer function -----------------------------------------------------------------------------------------
    def set_preset(self, name: str, *, force: bool = False) -> None:
        """Switch to a named preset, keeping the current shading choice. A preset made for another modality (a CT
        preset in HU on MR data) is refused unless ``force``, and then applied with a ``notice``."""
        volume = self.require_volume()
        function = transfer_function_for(volume, name)
        if not preset_suits(volume, name):
            message = (f"the preset {name} is made for {PRESETS[name].units} values (CT); this volume is "
                       f"{volume.modality or 'of unknown modality'} in {volume.units_label}")
            if not force:
                raise ValueError(message + "; choose one of " + ", ".join(presets_for(volume)))
            self.notice.emit(message[0].upper() + message[1:] + ": its colours and opacities may show nothing "
                             "meaningful.")
        shading = self.transfer_function.shading if self.transfer_function else None
        if shading is not None:
            function = function.with_shading(shading)
        self.set_transfer_function(function, preset=name, label=f"Preset {name}")

    def preset_warning(self) -> str:
        """A warning when the preset on show was not made for the volume's modality, else ""."""
        volume = self.volume
        if volume is None or not self.preset or self.preset not in PRESETS or preset_suits(volume, self.preset):
            return ""
        return f"{self.preset} is a CT preset (HU); this volume is in {volume.units_label}"

    def set_transfer_function(self, function: TransferFunction, *, preset: str | None = None,
                              label: str = "Transfer function") -> None:
        if function != self.transfer_function or (preset is not None and preset != self.preset):
            before = (self.transfer_function, self.preset)
            self.transfer_function = function
            if preset is not None:
                self.preset = preset
            after = (function, self.preset)
            self.transfer_function_changed.emit(function)
            self._record(label, lambda: self._restore_transfer(*before), lambda: self._restore_transfer(*after))

    def _restore_transfer(self, function, preset) -> None:
        self.preset = preset
        self.set_transfer_function(function)

    def set_opacity_points(self, points: Sequence[Sequence[float]]) -> None:
        """Replace the opacity curve (the curve editor's drag); points are (value, opacity) rows."""
        if self.transfer_function is None:
            raise ValueError("no transfer function to edit")
        self.set_transfer_function(self.transfer_function.with_opacity_points(points), label="Opacity points")

    def set_color_points(self, points: Sequence[Sequence[float]]) -> None:
        """Replace the colour curve; points are (value, r, g, b) rows, colours in [0, 1]."""
        if self.transfer_function is None:
            raise ValueError("no transfer function to edit")
        self.set_transfer_function(self.transfer_function.with_color_points(points), label="Colour points")

    def set_shading(self, **changes) -> None:
        """Change shading terms: ``enabled``, ``ambient``, ``diffuse``, ``specular``, ``specular_power``."""
        if self.transfer_function is None:
            raise ValueError("no transfer function to edit")
        shading: Shading = replace(self.transfer_function.shading, **changes)
        self.set_transfer_function(self.transfer_function.with_shading(shading), label="Shading")

    # -- slices ------------------------------------------------------------------------------------------------------
    def set_window_level(self, window: float, level: float) -> None:
        window, level = float(window), float(level)
        if not (np.isfinite(window) and np.isfinite(level)) or window <= 0:
            raise ValueError(f"window must be a positive number and level finite, got {window}, {level}")
        if (window, level) != (self.window, self.level):
            self.window, self.level = window, level
            self.window_level_changed.emit(window, level)

    def set_cursor(self, point: Sequence[float]) -> None:
        """Move the slice cursor to an LPS point, clamped to the base volume."""
        volume = self.base_volume
        if volume is None:
            raise ValueError("no volume is open")
        ijk = np.clip(volume.world_to_index(point), 0, np.asarray(volume.dimensions) - 1)
        clamped = volume.index_to_world(ijk)
        if not np.allclose(clamped, self.cursor):
            self.cursor = clamped
            self.cursor_changed.emit(clamped)

    def set_slice_rotation(self, rotation) -> None:
        """The oblique rotation shared by the three slice planes (3x3 rotation; identity: standard planes)."""
        rotation = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
        if not (np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6) and np.linalg.det(rotation) > 0):
            raise ValueError("the slice rotation must be a 3x3 rotation matrix")
        if not np.allclose(rotation, self.slice_rotation, atol=1e-12):
            before = self.slice_rotation.copy()
            self.slice_rotation = rotation
            self.slice_rotation_changed.emit(rotation)
            self._record("Oblique slices", lambda: self.set_slice_rotation(before),
                         lambda: self.set_slice_rotation(rotation), merge_key="slice-rotation")

    def rotate_slices(self, plane: str, degrees: float) -> None:
        """Rotate the crosshair in ``plane``'s view by ``degrees`` (counter-clockwise on screen): the two other
        planes turn about this plane's normal (oblique reformatting)."""
        if plane not in PLANES:
            raise ValueError(f"plane must be one of {', '.join(PLANES)}, got {plane!r}")
        normal = plane_frame(plane, self.slice_rotation).n
        self.set_slice_rotation(rotation_about(normal, degrees) @ self.slice_rotation)

    def set_interpolation(self, interpolation: str) -> None:
        """How the slice views sample the volume: ``linear`` (trilinear) or ``nearest``."""
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {', '.join(INTERPOLATIONS)}, got {interpolation!r}")
        if interpolation != self.interpolation:
            self.interpolation = interpolation
            self.slice_display_changed.emit()

    def set_label_opacity(self, opacity: float) -> None:
        """Opacity of label colours over the grey-value slices, 0 to 1."""
        opacity = float(opacity)
        if not 0.0 <= opacity <= 1.0:
            raise ValueError(f"label opacity must lie in [0, 1], got {opacity}")
        if opacity != self.label_opacity:
            self.label_opacity = opacity
            self.slice_display_changed.emit()

    # -- measurements ----------------------------------------------------------------------------------------------
    def add_measurement(self, measurement: Measurement, index: int | None = None) -> Measurement:
        """Measure on the volume of the slice views and add it to the list (undoable)."""
        mask_volume = None
        if measurement.kind == "mask":
            mask_volume = self.scene.get(measurement.mask).volume
        measurement.compute(self.base_volume, mask_volume=mask_volume)
        self.measurements.add(measurement, index)
        self._record(f"Add {measurement.name}", lambda: self.remove_measurement(measurement),
                     lambda: self.add_measurement(measurement, index))
        return measurement

    def remove_measurement(self, measurement: Measurement) -> None:
        index = self.measurements.remove(measurement)
        self._record(f"Remove {measurement.name}", lambda: self.add_measurement(measurement, index),
                     lambda: self.remove_measurement(measurement))

    # -- undo ------------------------------------------------------------------------------------------------------
    def _record(self, label: str, undo: Callable[[], None], redo: Callable[[], None], merge_key: str = "") -> None:
        if self._replaying:
            return
        self.undoable.emit(Change(label, self._replayed(undo), self._replayed(redo), merge_key))

    def _replayed(self, action: Callable[[], None]) -> Callable[[], None]:
        def run() -> None:
            with self.replaying():
                action()
        return run

    @contextmanager
    def replaying(self):
        """Changes made inside are not announced as new undoable edits (undo and redo themselves, sessions)."""
        self._replaying += 1
        try:
            yield
        finally:
            self._replaying -= 1

    # -- views ---------------------------------------------------------------------------------------------------------
    def set_layout(self, layout: str) -> None:
        if layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
        if layout != self.layout:
            self.layout = layout
            self.layout_changed.emit(layout)

    @property
    def view_count(self) -> int:
        rows, columns = LAYOUTS[self.layout]
        return rows * columns

    def _check_index(self, index: int) -> None:
        if not 0 <= index < MAX_VIEWS:
            raise ValueError(f"view index must be 0 to {MAX_VIEWS - 1}, got {index}")

    def set_view_mode(self, index: int, mode: str, options: dict[str, Any] | None = None) -> None:
        """Show ``mode`` in view ``index`` (its options at their defaults unless given)."""
        self._check_index(index)
        resolved = get_mode(mode).resolve_options(options)  # validates the name and the options
        given = {k: v for k, v in (options or {}).items()}
        if self.view_modes[index] != mode or self.view_options[index] != given:
            self.view_modes[index] = mode
            self.view_options[index] = given
            self.view_mode_changed.emit(index, mode, resolved)

    def set_view_options(self, index: int, **values: Any) -> None:
        """Change options of view ``index``'s mode (validated by the mode)."""
        self._check_index(index)
        mode = get_mode(self.view_modes[index])
        options = {**self.view_options[index], **values}
        resolved = mode.resolve_options(options)
        if options != self.view_options[index]:
            self.view_options[index] = options
            self.view_options_changed.emit(index, resolved)

    def set_cameras_linked(self, linked: bool) -> None:
        linked = bool(linked)
        if linked != self.cameras_linked:
            self.cameras_linked = linked
            self.cameras_linked_changed.emit(linked)


def _overlap(a: Volume, b: Volume) -> bool:
    """True when the boxes of two volumes overlap in the patient."""
    ba, bb = np.asarray(a.world_bounds), np.asarray(b.world_bounds)
    return bool(np.all(ba[0::2] <= bb[1::2]) and np.all(bb[0::2] <= ba[1::2]))
