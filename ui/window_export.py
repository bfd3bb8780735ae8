"""The workbench window's exports: the surface of a view as a mesh file with its sidecar, and screenshots of a
view, of the grid of views or of the whole window. A mixin of :class:`ui.main_window.MainWindow`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from qtpy.QtWidgets import QFileDialog, QMessageBox

from app.io import FileExistsRefusal
from app.meshing import MeshTooLargeError, export_mesh, sidecar_path
from app.pipeline import write_png
from app.workbench import LAYOUTS

from .dialogs import ExportOptionsDialog
from .tasks import Task

MESH_FILTER = "STL (*.stl);;PLY (*.ply);;OBJ (*.obj);;VTK polydata (*.vtp)"


class ExportActions:
    # -- export and screenshots --------------------------------------------------------------------------------
    def _surface_view(self):
        active = self.views[self.active_view]
        if active.isVisible() and active.current_surface() is not None:
            return active
        for view in self.views[: self.model.view_count]:
            if view.current_surface() is not None:
                return view
        return None

    def export_mesh(self) -> None:
        """Export the surface of the active view (or the first surface view) with its JSON sidecar."""
        view = self._surface_view()
        if view is None:
            self._report_error("No view shows a finished surface. Switch a view to a surface mode (for example "
                               "flying-edges) and wait for it to be built, then export.", "Nothing to export")
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export mesh", self._last_folder(), MESH_FILTER)
        if not path:
            return
        path = Path(path)
        if path.suffix.lower() not in (".stl", ".ply", ".obj", ".vtp"):
            path = path.with_suffix(".stl")
        # The file dialog confirmed replacing the mesh file itself; the sidecar is asked about separately.
        overwrite = path.exists()
        side = sidecar_path(path)
        if side.exists() and not self._confirm(f"{side.name} already exists. Replace it?"):
            return
        overwrite = overwrite or side.exists()
        options = ExportOptionsDialog.ask(str(path), self)
        if options is None:
            return
        self._start_mesh_export(view, path, options, overwrite)

    def _start_mesh_export(self, view, path: Path, options: dict, overwrite: bool, allow_large: bool = False) -> None:
        close_edges = options.get("close_edges", False)
        volume, result = self.export_source(view), None if close_edges else view.current_surface()
        task = Task(f"Exporting {path.name}", export_mesh, volume, path, method=view.mode,
                    iso=view.pipeline.inputs.iso, options=view.pipeline.options,
                    coordinates=options["coordinates"], cleanup=options["cleanup"], close_edges=close_edges,
                    overwrite=overwrite, result=result, allow_large=allow_large)
        task.finished.connect(lambda export: self.statusBar().showMessage(
            f"Wrote {export.paths[0]} ({export.written['triangles']:,} triangles, {options['coordinates']} mm) and its "
            f"sidecar", 15000))

        def failed(exc: BaseException) -> None:
            # A very large surface is not an error but a question: the user decides whether to write it.
            if isinstance(exc, MeshTooLargeError) and not allow_large:
                question = (f"The surface has about {exc.triangles:,} triangles, more than the {exc.limit:,} an export "
                            "makes without asking; clean-up, validation and writing may take minutes and several GiB."
                            f"\n\nWrite all of them to {path.name} anyway?")
                if self._confirm(question):
                    self._start_mesh_export(view, path, options, overwrite, allow_large=True)
                return
            self._report_error(f"Could not export {path}:\n\n{exc}", "Export failed")

        task.failed.connect(failed)
        self.tasks.start(task)

    def _confirm(self, question: str) -> bool:
        return QMessageBox.question(self, "Voxelscope", question) == QMessageBox.Yes

    def grab_views(self) -> np.ndarray:
        """All visible views in their grid as one ``(h, w, 3)`` uint8 image."""
        rows, columns = LAYOUTS[self.model.layout]
        captures = [view.capture() for view in self.views[: rows * columns]]
        height = max(c.shape[0] for c in captures)
        width = max(c.shape[1] for c in captures)
        canvas = np.zeros((rows * height, columns * width, 3), dtype=np.uint8)
        for index, capture in enumerate(captures):
            r, c = divmod(index, columns)
            canvas[r * height: r * height + capture.shape[0], c * width: c * width + capture.shape[1]] = capture
        return canvas

    def grab_window(self) -> np.ndarray:
        """The whole window (controls, views, slices) as ``(h, w, 3)`` uint8."""
        from qtpy.QtGui import QImage

        image = self.grab().toImage().convertToFormat(QImage.Format_RGB888)
        width, height = image.width(), image.height()
        buffer = np.frombuffer(image.constBits(), dtype=np.uint8, count=image.sizeInBytes())
        return buffer.reshape(height, image.bytesPerLine())[:, : width * 3].reshape(height, width, 3).copy()

    def save_view_screenshot(self) -> None:
        self._save_png(lambda: self.views[self.active_view].capture(), "Save view screenshot")

    def save_grid_screenshot(self) -> None:
        self._save_png(self.grab_views, "Save screenshot of all views")

    def _save_png(self, grab, title: str) -> None:
        path, _ = QFileDialog.getSaveFileName(self, title, self._last_folder(), "PNG image (*.png)")
        if not path:
            return
        path = Path(path) if path.lower().endswith(".png") else Path(path + ".png")
        try:
            write_png(grab(), path, overwrite=path.exists())  # the dialog asked before replacing
        except (OSError, ValueError, FileExistsRefusal) as exc:
            self._report_error(f"Could not save {path}:\n\n{exc}")
            return
        self.statusBar().showMessage(f"Saved {path}", 10000)
