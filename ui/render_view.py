"""One 3D view of the workbench: a header (grouped mode chooser, the mode's options, live statistics) above a
PyVista Qt view.

What the view shows is decided by the shared view pipeline of ``app`` (:class:`app.pipeline.ViewPipeline`), the
same one ``voxelscope render`` uses; this widget only hosts it: it gives the pipeline the renderer, a job runner on
the workbench's thread pool and the viewport size, renders when the pipeline asks, and forwards camera movement
and rest. Nothing here depends on what kind of mode is on show.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pyvistaqt import QtInteractor
from qtpy.QtCore import QEvent, QTimer, Signal
from qtpy.QtWidgets import QFrame, QHBoxLayout, QLabel, QSizePolicy, QToolButton, QVBoxLayout

from app.pipeline import ViewInputs, ViewPipeline

from .mode_chooser import ModeChooser
from .options_panel import OptionsPanel
from .tasks import QtJobRunner, TaskRunner

IDLE_MILLISECONDS = 250  # camera at rest this long -> full-quality frame
INTERACTIVE_UPDATE_RATE = 8.0  # frames per second VTK's volume mappers aim for while the camera moves
STILL_UPDATE_RATE = 0.0001


def _orientation_cube():
    """An annotated cube labelled with the LPS directions: L/R on x, P/A on y, S/I on z."""
    from vtkmodules.vtkRenderingAnnotation import vtkAnnotatedCubeActor

    cube = vtkAnnotatedCubeActor()
    for face, text in (("XPlus", "L"), ("XMinus", "R"), ("YPlus", "P"), ("YMinus", "A"), ("ZPlus", "S"),
                       ("ZMinus", "I")):
        getattr(cube, f"Set{face}FaceText")(text)
    cube.SetFaceTextScale(0.65)
    cube.GetCubeProperty().SetColor(0.25, 0.3, 0.4)
    cube.GetTextEdgesProperty().SetColor(0.8, 0.8, 0.8)
    for axis, color in (("X", (1.0, 0.6, 0.6)), ("Y", (0.6, 1.0, 0.6)), ("Z", (0.6, 0.7, 1.0))):
        for side in ("Plus", "Minus"):
            getattr(cube, f"Get{axis}{side}FaceProperty")().SetColor(*color)
    return cube


class RenderView(QFrame):
    """A view showing a scene item in one render mode."""

    mode_chosen = Signal(int, str)  # index, mode name (the user picked it in the header)
    options_chosen = Signal(int, object)  # index, {option: value} (the user changed the options panel)
    ready = Signal(int)  # a full-quality frame of the current content is on screen
    activated = Signal(int)  # the user clicked into this view
    failed = Signal(str)  # a message for the user

    def __init__(self, index: int, tasks: TaskRunner, parent=None) -> None:
        super().__init__(parent)
        self.index = index
        self.setFrameShape(QFrame.StyledPanel)
        self.setObjectName(f"view{index}")

        self.mode_box = ModeChooser()
        self.mode_box.setToolTip("Render mode of this view")
        self.mode_box.mode_activated.connect(lambda name: self.mode_chosen.emit(self.index, name))
        self.options_panel = OptionsPanel(self)
        self.options_panel.changed.connect(lambda values: self.options_chosen.emit(self.index, values))
        self.options_button = QToolButton()
        self.options_button.setText("Options")
        self.options_button.setObjectName("options")
        self.options_button.setToolTip("Options of this view's render mode")
        self.options_button.clicked.connect(self._toggle_options)
        self.stats_label = QLabel("")
        self.stats_label.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Preferred)
        self.stats_label.setObjectName("stats")
        header = QHBoxLayout()
        header.setContentsMargins(4, 2, 4, 2)
        header.addWidget(self.mode_box)
        header.addWidget(self.options_button)
        header.addWidget(self.stats_label, 1)

        self.plotter = QtInteractor(self, auto_update=False, multi_samples=0)
        self.plotter.set_background("black")
        self.renderer = self.plotter.renderer
        self.plotter.add_orientation_widget(_orientation_cube(), interactive=False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(1, 1, 1, 1)
        layout.setSpacing(0)
        layout.addLayout(header)
        layout.addWidget(self.options_panel)
        layout.addWidget(self.plotter.interactor, 1)
        self.options_panel.hide()

        self.pipeline = ViewPipeline(self.renderer, QtJobRunner(tasks), self._viewport_pixels)
        self.pipeline.changed.connect(lambda still: self.render(still=still))
        self.pipeline.status.connect(self._show_status)
        self.pipeline.ready.connect(lambda: self.ready.emit(self.index))
        self.pipeline.failed.connect(self.failed.emit)
        self._idle = QTimer(self)
        self._idle.setSingleShot(True)
        self._idle.setInterval(IDLE_MILLISECONDS)
        self._idle.timeout.connect(self.pipeline.camera_rested)
        self.plotter.interactor.installEventFilter(self)

    # -- what the main window calls --------------------------------------------------------------------------------
    @property
    def mode(self) -> str:
        return self.pipeline.mode.name if self.pipeline.mode is not None else ""

    @property
    def item(self):
        return self.pipeline.inputs.item if self.pipeline.inputs is not None else None

    @property
    def is_ready(self) -> bool:
        return self.pipeline.is_ready

    def show_item(self, inputs: ViewInputs, mode: str, options: dict[str, Any]) -> None:
        """Show a new item with the view's mode (the chooser lists the modes that can show it)."""
        inputs.interactive = True
        inputs.background = tuple(self.renderer.GetBackground())
        self.mode_box.set_item(inputs.item)
        self.mode_box.set_current(mode)
        self.pipeline.set_inputs(inputs, mode, options)
        self._mode_shown()

    def set_mode(self, mode: str, options: dict[str, Any] | None = None) -> None:
        self.mode_box.set_current(mode)
        self.pipeline.set_mode(mode, options)
        self._mode_shown()

    def _mode_shown(self) -> None:
        self.options_panel.set_mode(self.pipeline.mode, self.pipeline.options)
        self.options_button.setEnabled(bool(self.pipeline.mode.options))

    def set_options(self, options: dict[str, Any]) -> None:
        self.pipeline.set_options(**options)
        self.options_panel.set_values(self.pipeline.options)

    def set_iso(self, iso: float, *, preview: bool = False) -> None:
        self.pipeline.set_iso(iso, preview=preview)

    def set_transfer_function(self, transfer_function) -> None:
        self.pipeline.set_transfer_function(transfer_function)

    def camera_moved(self) -> None:
        """The camera this view shows was changed (here or in a linked view)."""
        self.pipeline.camera_moved(moving=True)
        self._idle.start()

    def render(self, *, still: bool = True) -> None:
        """Draw now; ``still=False`` lets VTK's volume mappers trade quality for speed (camera in motion)."""
        self.plotter.ren_win.SetDesiredUpdateRate(STILL_UPDATE_RATE if still else INTERACTIVE_UPDATE_RATE)
        self.renderer.ResetCameraClippingRange()
        self.plotter.render()

    def capture(self) -> np.ndarray:
        """The view's current frame as ``(h, w, 3)`` uint8, row 0 at the top."""
        image = self.plotter.screenshot(return_img=True)
        return np.ascontiguousarray(image[..., :3])

    def current_surface(self):
        """The full-resolution surface on show (volume frame), or None."""
        return self.pipeline.surface()

    def shutdown(self) -> None:
        self._idle.stop()
        self.pipeline.shutdown()
        self.plotter.close()

    # -- Qt -------------------------------------------------------------------------------------------------------
    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        if event.type() == QEvent.MouseButtonPress:
            self.activated.emit(self.index)
        elif event.type() == QEvent.Resize and self.pipeline.content is not None:
            # Software renderers draw at the view's pixel size: a resized view gets a new frame once it settles.
            self._idle.start()
            self.pipeline.viewport_resized()
        return False

    def _viewport_pixels(self) -> tuple[int, int]:
        width, height = self.plotter.ren_win.GetSize()
        return int(width), int(height)

    def _toggle_options(self) -> None:
        self.options_panel.setVisible(not self.options_panel.isVisible())

    def _show_status(self, text: str) -> None:
        self.stats_label.setText(text)
        self.stats_label.setToolTip(text)
