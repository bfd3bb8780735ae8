"""A slice view (axial, coronal or sagittal) as in 3D Slicer or ITK-SNAP: the volume reformatted on the plane through
the crosshair (:mod:`app.slices`), with zoom and pan, linear or nearest interpolation, window/level, label maps and
other fields drawn over it, the crosshair lines of the two other planes, and the measurements lying in the plane.

The orientation letters, the slice position and the hover read-out sit in margins around the image and never cover
it. Axial and coronal views show the patient's left on the screen's right (radiological convention).

Mouse (Navigate tool): left button sets the crosshair (Ctrl+left drag rotates it: oblique reformatting), right
button drags window (horizontal) and level (vertical), middle button (or Shift+left) pans, the wheel steps through
slices, Ctrl+wheel zooms about the pointer, a double-click enlarges the view (and back). The Distance, Angle and
Ellipse tools measure with the left button; everything is computed in ``app``.
"""

from __future__ import annotations

import math

import numpy as np
from qtpy.QtCore import QPointF, QRectF, Qt, Signal
from qtpy.QtGui import QColor, QFont, QImage, QPainter, QPen
from qtpy.QtWidgets import QSizePolicy, QWidget

from app.slices import PLANE_COLORS, PLANES, POSITION_AXIS, plane_frame, plane_grid, sample_plane, value_at
from app.volume import Volume

MARGIN_SIDE, MARGIN_TOP, MARGIN_BOTTOM = 16, 30, 30
MIN_ZOOM, MAX_ZOOM = 0.25, 40.0
TOOLS = ("navigate", "distance", "angle", "ellipse")


def _qcolor(rgb, alpha: int = 255) -> QColor:
    return QColor(int(rgb[0] * 255), int(rgb[1] * 255), int(rgb[2] * 255), alpha)


class SliceView(QWidget):
    """One slice plane of the model's base volume at the model's cursor."""

    cursor_picked = Signal(object)  # LPS point
    window_level_dragged = Signal(float, float)
    rotate_requested = Signal(str, float)  # plane, degrees (counter-clockwise on screen)
    measured = Signal(object)  # dict: kind, points (LPS), plane, frame, radii - a new measurement
    enlarge_requested = Signal(object)  # this view
    drag_finished = Signal()  # a drag that changed the model (crosshair rotation) ended: one undo step

    def __init__(self, plane: str, parent=None) -> None:
        super().__init__(parent)
        if plane not in PLANES:
            raise ValueError(f"plane must be one of {', '.join(PLANES)}, got {plane!r}")
        self.plane = plane
        self.setObjectName(f"slice-{plane}")
        self.setMinimumSize(160, 160)
        self.setSizePolicy(QSizePolicy.Expanding, QSizePolicy.Expanding)
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.ClickFocus)
        self.volume: Volume | None = None
        self.cursor = np.zeros(3)
        self.rotation = np.eye(3)
        self.window, self.level = 400.0, 40.0
        self.interpolation = "linear"
        self.base_table = None  # LabelTable when the base volume is itself a label map
        self.label_opacity = 0.5
        self.overlays: list[tuple] = []  # (volume, role, label table or None)
        self.measurements = []  # app.measurements.Measurement objects to draw when they lie in this plane
        self.tool = "navigate"
        self.zoom = 1.0
        self.centre_st: tuple[float, float] | None = None  # plane coordinates at the viewport's centre
        self.grid = None
        self._pixels: np.ndarray | None = None
        self._image: QImage | None = None
        self._buffer = None
        self._key = None
        self._slice = 0
        self._hover = ""
        self._drag: dict | None = None
        self._clicks: list[np.ndarray] = []
        self._preview: np.ndarray | None = None
        self.painted = False  # a full paint with the current image happened (screenshots wait for it)

    # -- model binding -----------------------------------------------------------------------------------------
    def set_volume(self, volume: Volume, cursor, window: float, level: float, *, table=None) -> None:
        self.volume = volume
        self.base_table = table
        self.window, self.level = window, level
        self._hover = ""
        self._clicks, self._drag, self._preview = [], None, None
        self.reset_view(update=False)
        self._key = None
        self.set_cursor(cursor)

    @property
    def frame(self):
        return plane_frame(self.plane, self.rotation)

    def set_cursor(self, cursor, *, force: bool = False) -> None:
        if self.volume is None:
            return
        self.cursor = np.asarray(cursor, dtype=float)
        frame = self.frame
        offset = round(float((self.cursor - self.volume.centre) @ frame.n), 6)
        key = (offset, self.rotation.tobytes(), self.interpolation)
        ijk = self.volume.world_to_index(self.cursor)
        axis = int(np.argmax(np.abs(self.volume.direction.T @ frame.n)))
        self._slice = int(np.clip(int(round(float(ijk[axis]))), 0, self.volume.dimensions[axis] - 1))
        if force or key != self._key or self._pixels is None:
            self._key = key
            self.grid = plane_grid(self.volume, frame, self.cursor)
            order = 0 if self.interpolation == "nearest" or self.base_table is not None else 1
            self._pixels = sample_plane(self.volume, self.grid, order=order)
            self._rebuild_image()
        self.update()

    def set_rotation(self, rotation) -> None:
        self.rotation = np.asarray(rotation, dtype=float)
        self.set_cursor(self.cursor)

    def set_display(self, interpolation: str, label_opacity: float) -> None:
        changed = interpolation != self.interpolation
        self.interpolation, self.label_opacity = interpolation, label_opacity
        if changed:
            self.set_cursor(self.cursor, force=True)
        else:
            self._rebuild_image()
            self.update()

    def set_overlays(self, overlays: list[tuple]) -> None:
        """Fields to draw over the slices: ``(volume, role)`` or ``(volume, role, label table)`` each."""
        self.overlays = [tuple(o) + (None,) * (3 - len(o)) for o in overlays]
        self._rebuild_image()
        self.update()

    def set_window_level(self, window: float, level: float) -> None:
        self.window, self.level = window, level
        self._rebuild_image()
        self.update()

    def set_measurements(self, measurements) -> None:
        self.measurements = list(measurements)
        self.update()

    def set_tool(self, tool: str) -> None:
        if tool not in TOOLS:
            raise ValueError(f"tool must be one of {', '.join(TOOLS)}, got {tool!r}")
        self.tool = tool
        self._clicks, self._preview = [], None
        self.setCursor(Qt.ArrowCursor if tool == "navigate" else Qt.CrossCursor)
        self.update()

    # -- zoom and pan --------------------------------------------------------------------------------------------
    def reset_view(self, *, update: bool = True) -> None:
        self.zoom, self.centre_st = 1.0, None
        if update:
            self.update()

    def set_zoom(self, zoom: float, anchor: QPointF | None = None) -> None:
        """Zoom (1 = the whole slice fits), keeping the plane point under ``anchor`` (widget pixels) in place."""
        if self.grid is None:
            return
        zoom = float(np.clip(zoom, MIN_ZOOM, MAX_ZOOM))
        if anchor is not None:
            before = self.widget_to_plane(anchor.x(), anchor.y())
            self.zoom = zoom
            after = self.widget_to_plane(anchor.x(), anchor.y())
            cs, ct = self._centre()
            self.centre_st = (cs + before[0] - after[0], ct + before[1] - after[1])
        else:
            self.zoom = zoom
        self.update()

    def pan_pixels(self, dx: float, dy: float) -> None:
        """Move the picture by ``(dx, dy)`` screen pixels."""
        if self.grid is None:
            return
        scale = self._scale()
        cs, ct = self._centre()
        self.centre_st = (cs - dx / scale, ct + dy / scale)
        self.update()

    def viewport(self) -> QRectF:
        """Where the image may be drawn: the widget less the margins holding the letters and the read-outs."""
        return QRectF(MARGIN_SIDE, MARGIN_TOP, max(self.width() - 2 * MARGIN_SIDE, 1),
                      max(self.height() - MARGIN_TOP - MARGIN_BOTTOM, 1))

    def _centre(self) -> tuple[float, float]:
        if self.centre_st is not None:
            return self.centre_st
        s0, s1, t0, t1 = self.grid.extent
        return (s0 + s1) / 2, (t0 + t1) / 2

    def _scale(self) -> float:
        """Screen pixels per millimetre."""
        s0, s1, t0, t1 = self.grid.extent
        viewport = self.viewport()
        return min(viewport.width() / (s1 - s0), viewport.height() / (t1 - t0)) * self.zoom

    def plane_to_widget(self, s: float, t: float) -> QPointF:
        viewport, scale = self.viewport(), self._scale()
        cs, ct = self._centre()
        return QPointF(viewport.center().x() + (s - cs) * scale, viewport.center().y() - (t - ct) * scale)

    def widget_to_plane(self, x: float, y: float) -> tuple[float, float]:
        viewport, scale = self.viewport(), self._scale()
        cs, ct = self._centre()
        return cs + (x - viewport.center().x()) / scale, ct - (y - viewport.center().y()) / scale

    def world_to_widget(self, point) -> QPointF:
        s, t = self.grid.to_plane(point)
        return self.plane_to_widget(float(s), float(t))

    def widget_to_world(self, x: float, y: float) -> np.ndarray | None:
        """The LPS point under widget position ``(x, y)`` on this plane, None off the volume."""
        if self.grid is None or not self.viewport().contains(QPointF(x, y)):
            return None
        s, t = self.widget_to_plane(x, y)
        s0, s1, t0, t1 = self.grid.extent
        if not (s0 <= s <= s1 and t0 <= t <= t1):
            return None
        return self.grid.to_world(s, t)

    def image_rect(self) -> QRectF:
        """Where the whole slice image is drawn (it may reach beyond the viewport when zoomed)."""
        if self.grid is None:
            return QRectF()
        s0, s1, t0, t1 = self.grid.extent
        top_left, bottom_right = self.plane_to_widget(s0, t1), self.plane_to_widget(s1, t0)
        return QRectF(top_left, bottom_right)

    # -- drawing -------------------------------------------------------------------------------------------------
    def _rebuild_image(self) -> None:
        if self._pixels is None:
            return
        from app.overlays import overlay_rgba

        values = self._pixels
        outside = ~np.isfinite(values)
        if self.base_table is not None:
            rgba = overlay_rgba(values, "labels", table=self.base_table, opacity=1.0)
            rgb = rgba[..., :3] * rgba[..., 3:4]
        else:
            low = self.level - self.window / 2
            grey = np.clip((np.nan_to_num(values, nan=low) - low) / self.window, 0.0, 1.0).astype(np.float32)
            rgb = np.repeat(grey[..., None], 3, axis=2)
        order = 0 if self.interpolation == "nearest" else 1
        for volume, role, table in self.overlays:
            field = sample_plane(volume, self.grid, order=0 if role in ("labels", "mask") else order)
            rgba = overlay_rgba(field, role, table=table, opacity=self.label_opacity)
            rgb = rgb * (1.0 - rgba[..., 3:4]) + rgba[..., :3] * rgba[..., 3:4]
        rgb[outside] = 0.0
        self._buffer = np.ascontiguousarray(np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8))
        height, width = self._buffer.shape[:2]
        self._image = QImage(self._buffer.data, width, height, 3 * width, QImage.Format_RGB888)
        self.painted = False

    def paintEvent(self, event) -> None:  # noqa: N802 - Qt override
        painter = QPainter(self)
        painter.fillRect(self.rect(), QColor(0, 0, 0))
        if self._image is None or self.volume is None:
            painter.setPen(QColor(160, 160, 160))
            painter.drawText(self.rect(), Qt.AlignCenter, "No volume")
            painter.end()
            return
        viewport = self.viewport()
        painter.save()
        painter.setClipRect(viewport)
        painter.setRenderHint(QPainter.SmoothPixmapTransform, self.interpolation == "linear"
                              and self.base_table is None)
        painter.drawImage(self.image_rect(), self._image)
        self._draw_crosshair(painter)
        painter.setRenderHint(QPainter.Antialiasing, True)
        self._draw_measurements(painter)
        painter.restore()
        self._draw_margins(painter)
        painter.end()
        self.painted = True

    def _draw_crosshair(self, painter: QPainter) -> None:
        from app.slices import crosshair_lines

        centre = self.world_to_widget(self.cursor)
        length = 2.0 * (self.width() + self.height())
        for other, (du, dv) in crosshair_lines(self.plane, self.rotation).items():
            painter.setPen(QPen(_qcolor(PLANE_COLORS[other], 190), 1))
            dx, dy = du * length, -dv * length
            painter.drawLine(QPointF(centre.x() - dx, centre.y() - dy), QPointF(centre.x() + dx, centre.y() + dy))

    def _in_plane(self, point, tolerance: float) -> bool:
        return abs(float((np.asarray(point) - self.cursor) @ self.frame.n)) <= tolerance

    def _draw_measurements(self, painter: QPainter) -> None:
        tolerance = 0.5 * float(min(self.volume.spacing)) + 1e-6
        painter.setFont(QFont(painter.font().family(), 9))
        for measurement in self.measurements:
            painter.setPen(QPen(QColor(90, 220, 255), 1.5))
            if measurement.radii is not None:  # an ellipse
                normal = np.cross(*np.asarray(measurement.frame))
                if abs(abs(float(normal @ self.frame.n)) - 1) > 1e-6 or not self._in_plane(measurement.points[0],
                                                                                             tolerance):
                    continue
                centre = self.world_to_widget(measurement.points[0])
                scale = self._scale()
                painter.drawEllipse(centre, measurement.radii[0] * scale, measurement.radii[1] * scale)
                r = measurement.results
                painter.drawText(centre + QPointF(measurement.radii[0] * scale + 4, 0),
                                 f"{measurement.name}: mean {r.get('mean', 0):.1f} {r.get('value_units', '')}")
            elif len(measurement.points) >= 2 and all(self._in_plane(p, tolerance) for p in measurement.points):
                self._draw_polyline(painter, measurement.points, measurement.summary())
        if self._preview is not None and self._clicks:  # the measurement being made
            painter.setPen(QPen(QColor(255, 255, 255), 1.5))
            points = [*self._clicks, self._preview]
            if self.tool == "ellipse":
                a, b = (self.world_to_widget(p) for p in points)
                painter.drawEllipse(QRectF(a, b).normalized())
            else:
                self._draw_polyline(painter, points, "")

    def _draw_polyline(self, painter: QPainter, points, text: str) -> None:
        screen = [self.world_to_widget(p) for p in points]
        for a, b in zip(screen, screen[1:]):
            painter.drawLine(a, b)
        for p in screen:
            painter.drawEllipse(p, 2.5, 2.5)
        if text:
            painter.drawText(screen[-1] + QPointF(6, -6), text)

    def _draw_margins(self, painter: QPainter) -> None:
        labels = self.frame.labels()
        painter.setPen(QColor(230, 230, 120))
        painter.setFont(QFont(painter.font().family(), 10, QFont.Bold))
        width, height = self.width(), self.height()
        painter.drawText(QRectF(0, MARGIN_TOP - 16, width, 16), Qt.AlignHCenter | Qt.AlignVCenter, labels["top"])
        painter.drawText(QRectF(0, height - MARGIN_BOTTOM, width, 15), Qt.AlignHCenter | Qt.AlignVCenter,
                         labels["bottom"])
        painter.drawText(QRectF(0, MARGIN_TOP, MARGIN_SIDE, height - MARGIN_TOP - MARGIN_BOTTOM), Qt.AlignCenter,
                         labels["left"])
        painter.drawText(QRectF(width - MARGIN_SIDE, MARGIN_TOP, MARGIN_SIDE, height - MARGIN_TOP - MARGIN_BOTTOM),
                         Qt.AlignCenter, labels["right"])
        painter.setFont(QFont(painter.font().family(), 8))
        painter.setPen(_qcolor(PLANE_COLORS[self.plane]))
        axis = POSITION_AXIS[self.plane]
        oblique = " (oblique)" if self.frame.oblique else ""
        painter.drawText(QRectF(4, 0, width - 8, 14), Qt.AlignLeft | Qt.AlignVCenter,
                         f"{self.plane.capitalize()}{oblique}  {'xyz'[axis]} = {self.cursor[axis]:.1f} mm  "
                         f"zoom {self.zoom:.2g}x")
        painter.setPen(QColor(200, 200, 200))
        bottom = QRectF(4, height - 15, width - 8, 15)
        if self._hover:
            painter.drawText(bottom, Qt.AlignLeft | Qt.AlignVCenter, self._hover)
        elif self.base_table is None:
            painter.drawText(bottom, Qt.AlignLeft | Qt.AlignVCenter,
                             f"W {self.window:g} L {self.level:g} {self.volume.units_label}")

    # -- read-out ------------------------------------------------------------------------------------------------
    def hover_text(self, world) -> str:
        """What the read-out says at an LPS point: position, value, and label names under it."""
        order = 0 if self.interpolation == "nearest" or self.base_table is not None else 1
        value = value_at(self.volume, world, order=order)
        if value is None:
            return ""
        text = f"({world[0]:.1f}, {world[1]:.1f}, {world[2]:.1f}) mm LPS: "
        if self.base_table is not None:
            label = int(value)
            text += f"label {label} {self.base_table.name(label) if label else '(background)'}"
        else:
            text += f"{value:.6g} {self.volume.units_label}"
        for volume, role, table in self.overlays:
            if role == "labels":
                label = value_at(volume, world, order=0)
                if label:
                    text += f"  |  label {int(label)} {table.name(int(label)) if table is not None else ''}"
        return text

    def leaveEvent(self, event) -> None:  # noqa: N802
        self._hover = ""
        self.update()

    # -- mouse ---------------------------------------------------------------------------------------------------
    @staticmethod
    def _position(event) -> QPointF:
        return event.position() if hasattr(event, "position") else QPointF(event.pos())

    def mousePressEvent(self, event) -> None:  # noqa: N802
        if self.volume is None:
            return
        point = self._position(event)
        modifiers = event.modifiers()
        if event.button() == Qt.MiddleButton or (event.button() == Qt.LeftButton and modifiers & Qt.ShiftModifier):
            self._drag = {"what": "pan", "at": point}
        elif event.button() == Qt.RightButton:
            self._drag = {"what": "window", "at": point, "window": self.window, "level": self.level}
        elif event.button() == Qt.LeftButton and self.tool == "navigate":
            if modifiers & Qt.ControlModifier:
                centre = self.world_to_widget(self.cursor)
                self._drag = {"what": "rotate", "angle": math.atan2(-(point.y() - centre.y()), point.x() - centre.x())}
            else:
                self._drag = {"what": "cursor"}
                self._pick(point)
        elif event.button() == Qt.LeftButton:
            world = self.widget_to_world(point.x(), point.y())
            if world is None:
                return
            if self.tool in ("distance", "ellipse"):
                self._clicks = [world]
                self._drag = {"what": "measure"}
            else:  # angle: three clicks
                self._clicks.append(world)
                if len(self._clicks) == 3:
                    self._finish_measurement()
            self._preview = world
            self.update()

    def mouseMoveEvent(self, event) -> None:  # noqa: N802
        if self.volume is None:
            return
        point = self._position(event)
        drag = self._drag
        if drag is not None and drag["what"] == "pan":
            self.pan_pixels(point.x() - drag["at"].x(), point.y() - drag["at"].y())
            drag["at"] = point
        elif drag is not None and drag["what"] == "window":
            lo, hi = self.volume.value_range
            per_pixel = (hi - lo) / 1000.0
            new_window = max(1e-3, drag["window"] + (point.x() - drag["at"].x()) * per_pixel * 2)
            new_level = drag["level"] - (point.y() - drag["at"].y()) * per_pixel
            self.window_level_dragged.emit(new_window, new_level)
        elif drag is not None and drag["what"] == "rotate":
            centre = self.world_to_widget(self.cursor)
            angle = math.atan2(-(point.y() - centre.y()), point.x() - centre.x())
            delta = math.degrees(angle - drag["angle"])
            delta = (delta + 180.0) % 360.0 - 180.0
            if abs(delta) >= 0.5:
                drag["angle"] = angle
                self.rotate_requested.emit(self.plane, delta)
        elif drag is not None and drag["what"] == "cursor":
            self._pick(point)
        world = self.widget_to_world(point.x(), point.y())
        if self._clicks and world is not None:
            self._preview = world
        self._hover = self.hover_text(world) if world is not None else ""
        self.update()

    def mouseReleaseEvent(self, event) -> None:  # noqa: N802
        drag, self._drag = self._drag, None
        if drag is not None and drag["what"] == "rotate":
            self.drag_finished.emit()
        if drag is not None and drag["what"] == "measure" and self._clicks:
            point = self._position(event)
            world = self.widget_to_world(point.x(), point.y())
            if world is not None and np.linalg.norm(world - self._clicks[0]) > 1e-6:
                self._clicks.append(world)
                self._finish_measurement()
            else:
                self._clicks, self._preview = [], None
            self.update()

    def mouseDoubleClickEvent(self, event) -> None:  # noqa: N802
        if self.tool == "navigate" and event.button() == Qt.LeftButton:
            self.enlarge_requested.emit(self)

    def wheelEvent(self, event) -> None:  # noqa: N802
        if self.volume is None:
            return
        steps = 1 if event.angleDelta().y() > 0 else -1
        if event.modifiers() & Qt.ControlModifier:
            self.set_zoom(self.zoom * (1.25 if steps > 0 else 0.8), self._position(event))
            return
        self.step(steps)

    def step(self, steps: int) -> None:
        """Move the crosshair ``steps`` slices along this plane's normal (one voxel spacing each)."""
        frame = self.frame
        spacing = float(abs(self.volume.direction.T @ frame.n) @ np.asarray(self.volume.spacing))
        self.cursor_picked.emit(self.cursor + steps * spacing * frame.n)

    def _pick(self, point) -> None:
        world = self.widget_to_world(point.x(), point.y())
        if world is not None:
            self.cursor_picked.emit(world)

    def _finish_measurement(self) -> None:
        points, self._clicks, self._preview = self._clicks, [], None
        frame = self.frame
        if self.tool == "ellipse":
            a, b = (self.grid.to_plane(p) for p in points)
            centre = self.grid.to_world((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
            radii = [abs(b[0] - a[0]) / 2, abs(b[1] - a[1]) / 2]
            if min(radii) <= 0:
                return
            self.measured.emit({"kind": "ellipse", "points": [centre.tolist()], "plane": self.plane,
                                "frame": [frame.u.tolist(), frame.v.tolist()], "radii": radii})
        else:
            self.measured.emit({"kind": self.tool, "points": [p.tolist() for p in points], "plane": self.plane})
