"""One 3D view of the workbench: a header (grouped mode chooser, the mode's options, live statistics) above a
PyVista Qt view.

What the view shows is decided by the shared view pipeline of ``app`` (:class:`app.pipeline.ViewPipeline`), the
same one ``voxelscope render`` uses; this widget only hosts it: it gives the pipeline the renderer, a job runner on
the workbench's thread pool and the viewport size, renders when the pipeline asks, and forwards camera movement
and rest. Nothing here depends on what kind of mode is on show.

Beside the content it draws the three slice planes' outlines (the crosshair of the slice views, in 3D Slicer's
colours) and the distance and angle measurements; with a measuring tool chosen, a click picks the surface point
under the pointer instead of turning the camera.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from pyvistaqt import QtInteractor
from qtpy.QtCore import QEvent, Qt, QTimer, Signal
from qtpy.QtWidgets import QFrame, QHBoxLayout, QLabel, QSizePolicy, QToolButton, QVBoxLayout

from app.modes import get_mode
from app.pipeline import ViewInputs, ViewPipeline

from .mode_chooser import ModeChooser
from .options_panel import OptionsPanel
from .tasks import QtJobRunner, TaskRunner

IDLE_MILLISECONDS = 250  # camera at rest this long -> full-quality frame
ORIENTATION_MARKER_VIEWPORT = (0.0, 0.0, 0.11, 0.11)  # lower-left corner, a ninth of the view's width
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
    enlarge_requested = Signal(object)  # this view: show it alone (or go back to the layout)
    point_picked = Signal(object)  # LPS point picked with a measuring tool

    def __init__(self, index: int, tasks: TaskRunner, parent=None) -> None:
        super().__init__(parent)
        self.index = index
        self._shut_down = False  # after shutdown() nothing is shown or rendered any more
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
        self.enlarge_button = QToolButton()
        self.enlarge_button.setText("Enlarge")
        self.enlarge_button.setObjectName("enlarge")
        self.enlarge_button.setToolTip("Show this view alone (one big view); press again to go back")
        self.enlarge_button.clicked.connect(lambda: self.enlarge_requested.emit(self))
        header.addWidget(self.mode_box)
        header.addWidget(self.options_button)
        header.addWidget(self.stats_label, 1)
        header.addWidget(self.enlarge_button)

        self.plotter = QtInteractor(self, auto_update=False, multi_samples=0)
        self.plotter.set_background("black")
        self.renderer = self.plotter.renderer
        self.plotter.add_orientation_widget(_orientation_cube(), interactive=False,
                                            viewport=ORIENTATION_MARKER_VIEWPORT)
        self.tool = "navigate"
        self._press = None
        self._plane_actors: dict[str, Any] = {}
        self._measure_actors: list = []
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
        from .clip_plane import ClipPlaneWidget  # clip-plane widget (issue 16)

        self.clip_plane = ClipPlaneWidget(self)  # clip-plane widget (issue 16)

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
        inputs = replace(inputs, interactive=True, background=tuple(self.renderer.GetBackground()))
        self.mode_box.set_item(inputs.item)
        self.mode_box.set_current(mode)
        self.pipeline.set_inputs(inputs, get_mode(mode), options)
        self._mode_shown()

    def replace_item(self, item) -> None:
        """Show another item in the same mode with the same inputs (a finer region of a pyramid, issue 19)."""
        if self.pipeline.inputs is not None and not self._shut_down:
            self.pipeline.set_inputs(replace(self.pipeline.inputs, item=item))

    def set_mode(self, mode: str, options: dict[str, Any] | None = None) -> None:
        self.mode_box.set_current(mode)
        self.pipeline.set_mode(get_mode(mode), options)
        self._mode_shown()

    def _mode_shown(self) -> None:
        self.options_panel.set_mode(self.pipeline.mode, self.pipeline.options)
        self.options_button.setEnabled(bool(self.pipeline.mode.options))
        self.clip_plane.mode_changed()  # clip-plane widget (issue 16)

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
        self._shut_down = True
        self._idle.stop()
        self.pipeline.shutdown()
        self.plotter.close()
        # pyvistaqt (0.13, a QOpenGLWidget) keeps its GL context's surface as a Python wrapper of a QSurface, which is
        # not a QObject: PySide is not told when Qt deletes it with the widget, and while the wrapper lives PySide
        # hands it out for any new object Qt allocates at the same address (a stress run got a QSurface back from
        # QDockWidget.toggleViewAction). Dropping the interactor's context references releases the wrapper now.
        forget_context = getattr(self.plotter, "_forget_context", None)
        if forget_context is not None:
            forget_context()

    # -- slice planes, measurements and picking -------------------------------------------------------------------
    def set_slice_planes(self, outlines: dict, colors: dict) -> None:
        """Draw the slice planes' outlines (``{plane: vtkPolyData}`` in LPS mm) in their colours."""
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

        for plane, polydata in outlines.items():
            actor = self._plane_actors.get(plane)
            if actor is None:
                actor = vtkActor()
                actor.SetMapper(vtkPolyDataMapper())
                actor.GetProperty().SetColor(*colors[plane])
                actor.GetProperty().SetLineWidth(2.0)
                actor.GetProperty().LightingOff()
                actor.PickableOff()
                self.renderer.AddActor(actor)
                self._plane_actors[plane] = actor
            actor.GetMapper().SetInputData(polydata)
        self.render()

    def plane_outline_points(self, plane: str) -> np.ndarray:
        """The outline's points on show for ``plane`` (LPS mm), ``(n, 3)``."""
        from vtkmodules.util.numpy_support import vtk_to_numpy

        actor = self._plane_actors.get(plane)
        data = actor.GetMapper().GetInput() if actor is not None else None
        if data is None or data.GetPoints() is None:
            return np.zeros((0, 3))
        return vtk_to_numpy(data.GetPoints().GetData()).astype(float)

    def set_measurements(self, polylines: list) -> None:
        """Draw measurement polylines (each ``(m, 3)`` LPS points) over the content."""
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

        from app.slices import polyline_polydata

        for actor in self._measure_actors:
            self.renderer.RemoveActor(actor)
        self._measure_actors = []
        for points in polylines:
            actor = vtkActor()
            actor.SetMapper(vtkPolyDataMapper())
            actor.GetMapper().SetInputData(polyline_polydata(points))
            actor.GetProperty().SetColor(0.35, 0.86, 1.0)
            actor.GetProperty().SetLineWidth(2.5)
            actor.GetProperty().LightingOff()
            actor.PickableOff()
            self.renderer.AddActor(actor)
            self._measure_actors.append(actor)
        self.render()

    def set_tool(self, tool: str) -> None:
        self.tool = tool
        self.plotter.interactor.setCursor(Qt.ArrowCursor if tool == "navigate" else Qt.CrossCursor)

    def pick(self, x: float, y: float) -> np.ndarray | None:
        """The LPS point of the content under widget pixel ``(x, y)`` of the plotter, or None."""
        from vtkmodules.vtkRenderingCore import vtkCellPicker

        picker = vtkCellPicker()
        picker.SetTolerance(0.0005)
        ratio = self.plotter.interactor.devicePixelRatioF()
        height = self.plotter.ren_win.GetSize()[1]
        if not picker.Pick(x * ratio, height - 1 - y * ratio, 0.0, self.renderer):
            return None
        return np.asarray(picker.GetPickPosition(), dtype=float)

    # -- Qt -------------------------------------------------------------------------------------------------------
    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt override
        if self.tool != "navigate" and event.type() in (QEvent.MouseButtonPress, QEvent.MouseButtonRelease,
                                                        QEvent.MouseMove, QEvent.MouseButtonDblClick):
            if event.type() == QEvent.MouseButtonPress:
                self.activated.emit(self.index)
            if getattr(event, "button", lambda: None)() == Qt.LeftButton or event.type() == QEvent.MouseMove:
                if event.type() == QEvent.MouseButtonRelease:
                    position = event.position()
                    point = self.pick(position.x(), position.y())
                    if point is not None:
                        self.point_picked.emit(point)
                return True  # a measuring click does not turn the camera
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
