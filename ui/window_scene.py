"""The workbench window's scene actions: meshes drawn beside the item on show, fields drawn over the slices, and the
operations of the Operations menu run in a worker with their results added to the scene. A mixin of
:class:`ui.main_window.MainWindow`."""

from __future__ import annotations

from app.operations import get_operation
from app.overlays import overlay_volume

from .operation_dialog import OperationDialog
from .tasks import Task


class SceneActions:
    def _overlays_changed(self) -> None:
        others = [item for item in self.model.scene if item is not self.model.item]
        for view in self.views:
            view.pipeline.set_overlays(others)
        self._update_slice_overlays()

    def _update_slice_overlays(self) -> None:
        """Fields of the scene over the base volume's slices, resampled onto its grid in a worker (cached)."""
        base = self.model.base_volume
        fields = [item for item in self.model.overlays() if item is not self.model.base]
        if base is None:
            return
        wanted = {item.name for item in fields}
        self._overlay_cache = {k: v for k, v in self._overlay_cache.items() if k in wanted}
        missing = [item for item in fields if self._overlay_cache.get(item.name, (None,))[0] is not item]

        def show() -> None:
            overlays = [(self._overlay_cache[item.name][1], item.role, item.metadata.get("label_table"))
                        for item in fields if item.name in self._overlay_cache]
            overlays += self._cut_overlays()  # the region cut-away tools remove (window_cutaways, issue 15)
            for view in self.slice_views.values():
                view.set_overlays(overlays)

        if not missing:
            show()
            return
        for item in missing:
            task = Task(f"Overlay of {item.name}", overlay_volume, base, item)
            task.finished.connect(lambda volume, item=item: (self._overlay_cache.__setitem__(item.name, (item, volume)),
                                                              show()))
            task.failed.connect(lambda exc, item=item: self._report_error(f"Could not draw {item.name} over the "
                                                                          f"slices:\n\n{exc}"))
            self.tasks.start(task)

    # -- operations --------------------------------------------------------------------------------------------
    def run_operation(self, name: str, *, items: dict | None = None, options: dict | None = None) -> None:
        """Run a registered operation in a worker; without ``items`` its dialog asks for inputs and options."""
        operation = get_operation(name)
        if items is None:
            chosen = OperationDialog.ask(operation, self.model.scene, self, preferred=self.model.item)
            if chosen is None:
                return
            items, options = chosen
        try:
            operation.check_inputs(items)
            resolved = operation.resolve_options(options)
        except ValueError as exc:
            self._report_error(str(exc), operation.label)
            return
        task = Task(operation.label, lambda progress=None: operation.run(items, resolved, progress=progress))
        task.finished.connect(self._operation_done)
        task.failed.connect(lambda exc: self._report_error(f"{operation.label} failed:\n\n{exc}", operation.label))
        self.tasks.start(task)

    def _operation_done(self, result) -> None:
        item = self.model.scene.add(result.item)
        if item.kind != "mesh" or self.model.item is None:
            self.model.show_item(item)
        seconds = result.report.get("seconds")
        self.statusBar().showMessage(f"Made {item.name}" + (f" in {seconds:.2f} s" if seconds else ""), 15000)
        self.operation_finished.emit(item)

    def _remove_item(self, name: str) -> None:
        item = self.model.scene.get(name)
        if item is self.model.item:
            self._report_error(f"{name} is shown in the views; show another item first.", "Remove item")
            return
        self.model.scene.remove(name)
