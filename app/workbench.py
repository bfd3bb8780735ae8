"""The workbench's state, without Qt: the scene (volumes, fields, meshes, ...), the item the views show, the
isovalue, the transfer function, window/level, the layout of views, each view's render mode and options, camera
linking and the slice cursor.

Widgets in ``ui`` subscribe to the signals and write back through the setters; tests and scripts drive the same
object headless. Setters validate their input (ValueError with a clear message) and emit only on real changes.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from .events import Signal
from .meshing import default_iso
from .modes import get_mode, modes_for
from .scene import MeshItem, Scene, VolumeItem
from .transfer import Shading, TransferFunction, default_preset_name, transfer_function_for
from .volume import Volume

LAYOUTS = {"1x1": (1, 1), "1x2": (1, 2), "2x2": (2, 2)}
DEFAULT_MODES = ("flying-edges", "vtk-gpu", "vtk-marching-cubes", "vtk-cpu")
MESH_MODE = "mesh"
MAX_VIEWS = 4


def default_window_level(volume: Volume) -> tuple[float, float]:
    """A first window/level: the soft-tissue window (400/40 HU) for CT, the robust value range otherwise."""
    if volume.units == "HU":
        return 400.0, 40.0
    lo, hi = volume.percentile_range(0.5, 99.5)
    return hi - lo, 0.5 * (lo + hi)


def load_for_workbench(path, *, series_uid: str | None = None, progress=None):
    """Read a volume or a mesh file off the GUI thread. For a volume, also compute what the workbench shows at once
    (value range, robust range, histogram; cached on the volume). Returns a :class:`Volume` or a loaded mesh."""
    from algorithms.common.progress import scaled

    from .io import load_volume
    from .io.meshes import is_mesh_path, load_mesh

    if is_mesh_path(path):
        return load_mesh(path)
    volume = load_volume(path, series_uid=series_uid, progress=scaled(progress, 0.0, 0.9))
    volume.value_range
    volume.percentile_range()
    volume.histogram()
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
        to its defaults."""
        from pathlib import Path

        for old in self.scene.of_kind("volume"):
            self.scene.remove(old.name)
        self.base = None
        name = name or Path(volume.metadata.get("source_path", "") or "volume").name or "volume"
        item = self.scene.add(VolumeItem(name, volume=volume, metadata=dict(volume.metadata)))
        self.show_item(item)
        return item

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
                self.iso = default_iso(volume)
            self.preset = default_preset_name(volume)
            self.transfer_function = transfer_function_for(volume, self.preset)
        if new_base:
            self.base = item
            self.window, self.level = default_window_level(volume)
            self.cursor = volume.centre
        usable = {mode.name for mode in modes_for(item)}
        for index, mode in enumerate(self.view_modes):
            if mode not in usable:
                self.view_modes[index] = MESH_MODE if item.kind == "mesh" else DEFAULT_MODES[index]
                self.view_options[index] = {}
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
            self.iso = iso
            self.iso_changed.emit(iso)

    # -- transfer function -----------------------------------------------------------------------------------------
    def set_preset(self, name: str) -> None:
        """Switch to a named preset, keeping the current shading choice."""
        volume = self.require_volume()
        shading = self.transfer_function.shading if self.transfer_function else None
        function = transfer_function_for(volume, name)
        if shading is not None:
            function = function.with_shading(shading)
        self.preset = name
        self.set_transfer_function(function)

    def set_transfer_function(self, function: TransferFunction) -> None:
        if function != self.transfer_function:
            self.transfer_function = function
            self.transfer_function_changed.emit(function)

    def set_opacity_points(self, points: Sequence[Sequence[float]]) -> None:
        """Replace the opacity curve (the curve editor's drag); points are (value, opacity) rows."""
        if self.transfer_function is None:
            raise ValueError("no transfer function to edit")
        self.set_transfer_function(self.transfer_function.with_opacity_points(points))

    def set_color_points(self, points: Sequence[Sequence[float]]) -> None:
        """Replace the colour curve; points are (value, r, g, b) rows, colours in [0, 1]."""
        if self.transfer_function is None:
            raise ValueError("no transfer function to edit")
        self.set_transfer_function(self.transfer_function.with_color_points(points))

    def set_shading(self, **changes) -> None:
        """Change shading terms: ``enabled``, ``ambient``, ``diffuse``, ``specular``, ``specular_power``."""
        if self.transfer_function is None:
            raise ValueError("no transfer function to edit")
        shading: Shading = replace(self.transfer_function.shading, **changes)
        self.set_transfer_function(self.transfer_function.with_shading(shading))

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
