"""The workbench window's cut-away tools (issue 15; source 002, section 2.5): the model's
:class:`app.cutaways.Cutaways` (``model.cutaways``, stored in sessions), its widget in every 3D view
(:mod:`.tool_widgets`), the tool list dock (:mod:`.tool_panel`, a section of the control panel) and File > Export
cropped volume for a ``keep`` box. A mixin of :class:`ui.main_window.MainWindow`; the cut itself is the views'
pipelines' (``ViewPipeline.set_tools``)."""

from __future__ import annotations

from pathlib import Path

from qtpy.QtWidgets import QFileDialog, QGroupBox, QVBoxLayout

from app.cutaways import cropped_volume, default_tool

from .tasks import Task
from .tool_panel import ToolPanel
from .tool_widgets import ToolWidget

VOLUME_FILTER = "NIfTI (*.nii.gz *.nii);;NRRD (*.nrrd);;MetaImage (*.mha *.mhd)"


class CutawayActions:
    def _build_cutaways(self) -> None:
        self.current_tool = -1
        self.tool_widgets = [ToolWidget(view, self._tool_dragged) for view in self.views]
        self.tool_panel = ToolPanel()
        self.tool_panel.add_requested.connect(self.add_tool)
        self.tool_panel.remove_requested.connect(self.remove_tool)
        self.tool_panel.visibility_changed.connect(
            lambda index, on: self.model.cutaways.replace(index, self.model.cutaways.tools[index].moved(visible=on)))
        self.tool_panel.mode_changed.connect(self.set_tool_mode)
        self.tool_panel.evaluation_changed.connect(self.model.cutaways.set_evaluation)
        self.tool_panel.current_changed.connect(self._select_tool)
        # A section of the control panel (its scroll area grows; the views keep their size).
        box = QGroupBox("Cut-away tools")
        box.setObjectName("cut-away-tools")
        QVBoxLayout(box).addWidget(self.tool_panel)
        self.controls.layout().addWidget(box)
        self.model.cutaways.changed.connect(self._cutaways_changed)
        self._dragging_widget = None

    # -- what menus, the panel and tests call ------------------------------------------------------------------------
    def add_tool(self, shape: str = "box") -> int:
        """Add a tool of ``shape`` in the middle of the volume on show; it becomes the selected tool."""
        volume = self.model.volume
        if volume is None:
            self._report_error("Open a volume first: cut-away tools cut volumes.", "No volume")
            return -1
        self.current_tool = len(self.model.cutaways.tools)
        return self.model.cutaways.add(default_tool(shape, volume.world_bounds))

    def remove_tool(self, index: int) -> None:
        self.current_tool = min(self.current_tool, len(self.model.cutaways.tools) - 2)
        self.model.cutaways.remove(index)

    def set_tool_mode(self, index: int, mode: str) -> None:
        self.model.cutaways.replace(index, self.model.cutaways.tools[index].moved(mode=mode))

    def export_cropped_volume(self, path, *, overwrite: bool = False, progress=None) -> Path:
        """Write the region the ``keep`` tools leave (on the volume's grid) to ``path`` (NIfTI, NRRD, MetaImage)."""
        from app.io import save_volume

        volume = self.model.volume
        if volume is None:
            raise ValueError("open a volume first")
        return save_volume(cropped_volume(volume, self.model.cutaways.tools), path, overwrite=overwrite)

    def export_cropped_volume_dialog(self) -> None:
        if self.model.volume is None or not any(t.visible and t.mode == "keep" for t in self.model.cutaways.tools):
            self._report_error("Export of a cropped volume needs a tool in keep mode: add a box in the Cut-away "
                               "tools panel and set its mode to keep.", "Nothing to crop")
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export cropped volume", self._last_folder(), VOLUME_FILTER)
        if not path:
            return
        # The file dialog asked before replacing an existing file.
        task = Task(f"Exporting {Path(path).name}", self.export_cropped_volume, path, overwrite=Path(path).exists())
        task.finished.connect(lambda written: self.statusBar().showMessage(f"Wrote {written}", 15000))
        task.failed.connect(lambda exc: self._report_error(str(exc)))
        self.tasks.start(task)

    def export_source(self, view):
        """The volume a mesh export of ``view`` extracts from: with visible tools and a mode that honours them, the
        volume with the tools' CSG difference written in (so the exported surface is capped at the cut)."""
        from app.cutaways import cut_for_surface

        volume = self.model.volume
        mode = view.pipeline.mode
        if volume is None or mode is None or not mode.capabilities.accepts_cutaways:
            return volume
        return cut_for_surface(volume, self.model.cutaways.tools, view.pipeline.inputs.iso,
                               evaluation=self.model.cutaways.evaluation)

    def _cut_overlays(self) -> list:
        """The removed region over the slice views (a mask overlay), when it is up to date."""
        overlay = getattr(self, "_cut_overlay", None)
        return [] if overlay is None else [(overlay, "mask", None)]

    def _refresh_cut_overlay(self) -> None:
        """Recompute the removed region on the slice views' volume in a worker (after a tool settles)."""
        from app.cutaways import removed_overlay

        base = self.model.base_volume
        self._cut_overlay = None
        if base is None or not any(tool.visible for tool in self.model.cutaways.tools):
            self._update_slice_overlays()
            return
        self._cut_generation = getattr(self, "_cut_generation", 0) + 1
        generation = self._cut_generation

        def done(overlay) -> None:
            if generation == self._cut_generation:
                self._cut_overlay = overlay
                self._update_slice_overlays()

        task = Task("Shading the cut in the slices", removed_overlay, base, list(self.model.cutaways.tools))
        task.finished.connect(done)
        task.failed.connect(lambda exc: self._report_error(f"Could not shade the cut in the slices:\n\n{exc}"))
        self.tasks.start(task)

    # -- internals -------------------------------------------------------------------------------------------------
    def _select_tool(self, index: int) -> None:
        self.current_tool = index
        self._place_widgets()

    def _tool_dragged(self, widget, tool, moving: bool) -> None:
        if not 0 <= self.current_tool < len(self.model.cutaways.tools):
            return
        self._dragging_widget = widget if moving else None
        self.model.cutaways.replace(self.current_tool, tool, moving=moving)

    def _place_widgets(self) -> None:
        tools = self.model.cutaways.tools
        tool = tools[self.current_tool] if 0 <= self.current_tool < len(tools) else None
        for widget in self.tool_widgets:
            if widget is not self._dragging_widget:
                widget.show_tool(tool)

    def _cutaways_changed(self, moving: bool) -> None:
        cutaways = self.model.cutaways
        self._place_widgets()
        if not moving:
            self.tool_panel.show_tools(cutaways.tools, cutaways.evaluation, self.current_tool)
            self._refresh_cut_overlay()
        for view in self.views[: self.model.view_count]:
            if view.item is not None and getattr(view.item, "volume", None) is not None:
                view.pipeline.set_tools(cutaways.tools, cutaways.evaluation, moving=moving)
