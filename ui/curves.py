"""Two painted widgets of the control panel: the value histogram with the isovalue marker, and the transfer
function editor (opacity curve with draggable control points over the colour gradient)."""

from __future__ import annotations

import numpy as np
from qtpy.QtCore import QPointF, QRectF, Qt, Signal
from qtpy.QtGui import QBrush, QColor, QLinearGradient, QPainter, QPainterPath, QPen
from qtpy.QtWidgets import QSizePolicy, QWidget

MARGIN = 6


class HistogramWidget(QWidget):
    """Log-scaled histogram of the volume's values; a line marks the isovalue, clicking or dragging moves it."""

    iso_dragged = Signal(float)  # while dragging
    iso_released = Signal(float)  # at release

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setMinimumHeight(70)
        self.setSizePolicy(QSizePolicy.Expanding, QSizePolicy.Fixed)
        self.counts = np.zeros(1)
        self.edges = np.array([0.0, 1.0])
        self.iso = 0.0
        self.units = ""
        self._dragging = False

    def set_histogram(self, counts: np.ndarray, edges: np.ndarray, units: str) -> None:
        self.counts, self.edges, self.units = np.asarray(counts), np.asarray(edges), units
        self.update()

    def set_iso(self, iso: float) -> None:
        self.iso = iso
        self.update()

    def _x_of(self, value: float) -> float:
        lo, hi = self.edges[0], self.edges[-1]
        return MARGIN + (value - lo) / (hi - lo) * (self.width() - 2 * MARGIN)

    def _value_at(self, x: float) -> float:
        lo, hi = self.edges[0], self.edges[-1]
        fraction = np.clip((x - MARGIN) / max(1, self.width() - 2 * MARGIN), 0, 1)
        return float(lo + fraction * (hi - lo))

    def paintEvent(self, event) -> None:  # noqa: N802
        painter = QPainter(self)
        painter.fillRect(self.rect(), QColor(30, 30, 35))
        heights = np.log1p(self.counts.astype(float))
        top = heights.max() if heights.size and heights.max() > 0 else 1.0
        plot = QRectF(MARGIN, MARGIN, self.width() - 2 * MARGIN, self.height() - 2 * MARGIN - 12)
        path = QPainterPath(QPointF(plot.left(), plot.bottom()))
        for index, h in enumerate(heights):
            x = plot.left() + (index + 0.5) / len(heights) * plot.width()
            path.lineTo(QPointF(x, plot.bottom() - h / top * plot.height()))
        path.lineTo(QPointF(plot.right(), plot.bottom()))
        painter.fillPath(path, QBrush(QColor(110, 140, 180)))
        x = self._x_of(self.iso)
        painter.setPen(QPen(QColor(255, 190, 40), 2))
        painter.drawLine(QPointF(x, plot.top()), QPointF(x, plot.bottom()))
        painter.setPen(QColor(200, 200, 200))
        painter.drawText(QRectF(0, self.height() - 14, self.width(), 14), Qt.AlignLeft,
                         f" {self.edges[0]:g} {self.units}")
        painter.drawText(QRectF(0, self.height() - 14, self.width(), 14), Qt.AlignRight,
                         f"{self.edges[-1]:g} {self.units} ")
        painter.drawText(QRectF(0, self.height() - 14, self.width(), 14), Qt.AlignHCenter, "log(count)")
        painter.end()

    def mousePressEvent(self, event) -> None:  # noqa: N802
        self._dragging = True
        self.iso_dragged.emit(self._value_at(event.position().x()))

    def mouseMoveEvent(self, event) -> None:  # noqa: N802
        if self._dragging:
            self.iso_dragged.emit(self._value_at(event.position().x()))

    def mouseReleaseEvent(self, event) -> None:  # noqa: N802
        if self._dragging:
            self._dragging = False
            self.iso_released.emit(self._value_at(event.position().x()))


class TransferFunctionEditor(QWidget):
    """The opacity curve over the colour gradient.

    Opacity: drag a point to move it, double-click to add one, right-click to remove one (the end points stay).
    Colour: the markers under the gradient bar are the colour points; drag one along the value axis, double-click
    it to choose its colour. Emits the new points while dragging and at release.
    """

    points_dragged = Signal(object)  # list of (value, opacity)
    points_changed = Signal(object)
    color_points_changed = Signal(object)  # list of (value, r, g, b)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setMinimumHeight(110)
        self.setSizePolicy(QSizePolicy.Expanding, QSizePolicy.Fixed)
        self.value_range = (0.0, 1.0)
        self.opacity_points: list[list[float]] = [[0.0, 0.0], [1.0, 1.0]]
        self.color_points: list[tuple[float, float, float, float]] = [(0, 0, 0, 0), (1, 1, 1, 1)]
        self.max_opacity = 1.0
        self.units = ""
        self._drag: int | None = None
        self._drag_color: int | None = None

    def set_function(self, transfer_function, value_range: tuple[float, float], units: str) -> None:
        self.opacity_points = [list(p) for p in transfer_function.opacity_points]
        self.color_points = [list(p) for p in transfer_function.color_points]
        self.value_range = (float(value_range[0]), float(value_range[1]))
        self.units = units
        self.max_opacity = max(0.05, min(1.0, max(p[1] for p in self.opacity_points) * 1.25))
        self.update()

    # -- geometry -------------------------------------------------------------------------------------------
    def _plot(self) -> QRectF:
        return QRectF(MARGIN, MARGIN, self.width() - 2 * MARGIN, self.height() - 2 * MARGIN - 26)

    def _to_screen(self, value: float, opacity: float) -> QPointF:
        plot = self._plot()
        lo, hi = self.value_range
        x = plot.left() + (np.clip(value, lo, hi) - lo) / (hi - lo) * plot.width()
        y = plot.bottom() - opacity / self.max_opacity * plot.height()
        return QPointF(x, y)

    def _from_screen(self, point: QPointF) -> tuple[float, float]:
        plot = self._plot()
        lo, hi = self.value_range
        value = lo + np.clip((point.x() - plot.left()) / plot.width(), 0, 1) * (hi - lo)
        opacity = np.clip((plot.bottom() - point.y()) / plot.height(), 0, 1) * self.max_opacity
        return float(value), float(min(opacity, 1.0))

    def _color_bar(self) -> QRectF:
        plot = self._plot()
        return QRectF(plot.left(), plot.bottom() + 4, plot.width(), 8)

    def _nearest_color(self, point: QPointF, radius: float = 6.0) -> int | None:
        """The colour point whose marker (under the gradient bar) is at ``point``."""
        bar = self._color_bar()
        if not bar.top() - 2 <= point.y() <= bar.bottom() + 8:
            return None
        best, best_distance = None, radius
        for index, (value, *_rgb) in enumerate(self.color_points):
            distance = abs(self._to_screen(value, 0.0).x() - point.x())
            if distance <= best_distance:
                best, best_distance = index, distance
        return best

    def _nearest(self, point: QPointF, radius: float = 8.0) -> int | None:
        best, best_distance = None, radius
        for index, (value, opacity) in enumerate(self.opacity_points):
            p = self._to_screen(value, opacity)
            distance = np.hypot(p.x() - point.x(), p.y() - point.y())
            if distance <= best_distance:
                best, best_distance = index, distance
        return best

    # -- painting ----------------------------------------------------------------------------------------------
    def paintEvent(self, event) -> None:  # noqa: N802
        painter = QPainter(self)
        painter.setRenderHint(QPainter.Antialiasing)
        painter.fillRect(self.rect(), QColor(30, 30, 35))
        plot = self._plot()
        bar = self._color_bar()
        gradient = QLinearGradient(bar.left(), 0, bar.right(), 0)
        lo, hi = self.value_range
        for value, r, g, b in self.color_points:
            if lo <= value <= hi:
                gradient.setColorAt((value - lo) / (hi - lo), QColor.fromRgbF(r, g, b))
        painter.fillRect(bar, QBrush(gradient))
        painter.setPen(QPen(QColor(230, 230, 230), 1))
        for value, r, g, b in self.color_points:
            if lo <= value <= hi:
                x = self._to_screen(value, 0.0).x()
                marker = QPainterPath(QPointF(x, bar.bottom()))
                marker.lineTo(QPointF(x - 4, bar.bottom() + 6))
                marker.lineTo(QPointF(x + 4, bar.bottom() + 6))
                marker.closeSubpath()
                painter.fillPath(marker, QColor.fromRgbF(r, g, b))
                painter.drawPath(marker)
        path = QPainterPath()
        for index, (value, opacity) in enumerate(sorted(self.opacity_points)):
            point = self._to_screen(value, opacity)
            path.moveTo(point) if index == 0 else path.lineTo(point)
        painter.setPen(QPen(QColor(240, 240, 240), 1.5))
        painter.drawPath(path)
        painter.setBrush(QColor(255, 190, 40))
        for value, opacity in self.opacity_points:
            painter.drawEllipse(self._to_screen(value, opacity), 4, 4)
        painter.setPen(QColor(200, 200, 200))
        painter.drawText(QRectF(0, self.height() - 14, self.width(), 14), Qt.AlignLeft, f" {lo:g} {self.units}")
        painter.drawText(QRectF(0, self.height() - 14, self.width(), 14), Qt.AlignRight, f"{hi:g} {self.units} ")
        painter.drawText(plot.adjusted(4, 2, -4, -2), Qt.AlignLeft | Qt.AlignTop,
                         f"opacity per mm (top of the box = {self.max_opacity:.2f})")
        painter.end()

    # -- editing -----------------------------------------------------------------------------------------------
    def mousePressEvent(self, event) -> None:  # noqa: N802
        color = self._nearest_color(event.position())
        if color is not None and event.button() == Qt.LeftButton:
            self._drag_color = color
            return
        index = self._nearest(event.position())
        if event.button() == Qt.RightButton and index is not None and 0 < index < len(self.opacity_points) - 1:
            del self.opacity_points[index]
            self.update()
            self.points_changed.emit(self.points())
            return
        self._drag = index

    def mouseDoubleClickEvent(self, event) -> None:  # noqa: N802
        color = self._nearest_color(event.position())
        if color is not None:
            self._choose_color(color)
            return
        value, opacity = self._from_screen(event.position())
        self.opacity_points.append([value, opacity])
        self.opacity_points.sort()
        self.update()
        self.points_changed.emit(self.points())

    def _choose_color(self, index: int) -> None:
        from qtpy.QtWidgets import QColorDialog

        value, r, g, b = self.color_points[index]
        chosen = QColorDialog.getColor(QColor.fromRgbF(r, g, b), self, f"Colour at {value:g} {self.units}")
        if chosen.isValid():
            self.color_points[index] = [value, chosen.redF(), chosen.greenF(), chosen.blueF()]
            self.update()
            self.color_points_changed.emit(self.color_values())

    def mouseMoveEvent(self, event) -> None:  # noqa: N802
        if self._drag_color is not None:
            value, _ = self._from_screen(event.position())
            points, index = self.color_points, self._drag_color
            if index > 0:
                value = max(value, points[index - 1][0])
            if index < len(points) - 1:
                value = min(value, points[index + 1][0])
            points[index][0] = value
            self.update()
            return
        if self._drag is None:
            return
        value, opacity = self._from_screen(event.position())
        points = self.opacity_points
        # Points keep their order: a point cannot pass its neighbours.
        if self._drag > 0:
            value = max(value, points[self._drag - 1][0])
        if self._drag < len(points) - 1:
            value = min(value, points[self._drag + 1][0])
        points[self._drag] = [value, opacity]
        self.update()
        self.points_dragged.emit(self.points())

    def mouseReleaseEvent(self, event) -> None:  # noqa: N802
        if self._drag_color is not None:
            self._drag_color = None
            self.color_points_changed.emit(self.color_values())
        if self._drag is not None:
            self._drag = None
            self.points_changed.emit(self.points())

    def points(self) -> list[tuple[float, float]]:
        return [tuple(p) for p in self.opacity_points]

    def color_values(self) -> list[tuple[float, float, float, float]]:
        return [tuple(p) for p in self.color_points]
