"""Axial, coronal and sagittal slice views with window/level and a crosshair, oriented as radiologists expect.

Axial and coronal views show the patient's left on the screen's right (radiological convention); axial has the
anterior side up, coronal and sagittal the superior side up, sagittal the anterior side on the left. Slices run
along the volume's index axes nearest to each anatomical axis (no resampling), so an oblique acquisition is shown
in its own planes; the corner labels say which way is which.

Mouse: left button sets the crosshair (the other views follow), the wheel steps through slices, the right button
drags window (horizontal) and level (vertical).
"""

from __future__ import annotations

import numpy as np
from qtpy.QtCore import QPointF, QRectF, Qt, Signal
from qtpy.QtGui import QColor, QFont, QImage, QPainter, QPen
from qtpy.QtWidgets import QSizePolicy, QWidget

from app.volume import LPS_AXIS_LABELS, Volume

# plane -> (normal anatomical axis, (horizontal axis, sign of screen-right), (vertical axis, sign of screen-up))
PLANES = {
    "axial": (2, (0, +1), (1, -1)),
    "coronal": (1, (0, +1), (2, +1)),
    "sagittal": (0, (1, +1), (2, +1)),
}


def plane_axes(volume: Volume, plane: str) -> dict:
    """How ``plane`` maps onto the volume's index axes: slicing axis and the on-screen axes with their flips."""
    normal, (h_axis, h_sign), (v_axis, v_sign) = PLANES[plane]
    anatomical = np.argmax(np.abs(volume.direction), axis=0)  # for index axis a, its anatomical axis
    signs = np.sign(volume.direction[anatomical, np.arange(3)])
    if len(set(anatomical.tolist())) != 3:  # strongly oblique: fall back to i, j, k
        anatomical, signs = np.arange(3), np.ones(3)
    index_of = {int(anatomical[a]): a for a in range(3)}
    return {
        "slice_axis": index_of[normal],
        "horizontal": index_of[h_axis],
        "horizontal_flip": signs[index_of[h_axis]] != h_sign,
        "vertical": index_of[v_axis],
        # row 0 is at the top of the screen, so rows run against "up"
        "vertical_flip": signs[index_of[v_axis]] == v_sign,
        "labels": {
            "right": LPS_AXIS_LABELS[h_axis][1 if h_sign > 0 else 0],
            "left": LPS_AXIS_LABELS[h_axis][0 if h_sign > 0 else 1],
            "top": LPS_AXIS_LABELS[v_axis][1 if v_sign > 0 else 0],
            "bottom": LPS_AXIS_LABELS[v_axis][0 if v_sign > 0 else 1],
        },
    }


def slice_image(volume: Volume, plane: str, index: int) -> tuple[np.ndarray, dict]:
    """The 2D slice ``index`` of ``plane`` as (rows, columns) with row 0 at the top of the screen."""
    axes = plane_axes(volume, plane)
    array_axis = {0: 2, 1: 1, 2: 0}  # index axis -> NumPy axis of array[k, j, i]
    data = np.take(volume.array, index, axis=array_axis[axes["slice_axis"]])
    # Remaining NumPy axes in order; find where the vertical/horizontal index axes went.
    remaining = [a for a in (2, 1, 0) if a != axes["slice_axis"]]  # the index axes left, in NumPy axis order
    order = [remaining.index(axes["vertical"]), remaining.index(axes["horizontal"])]
    image = np.transpose(data, order)
    if axes["vertical_flip"]:
        image = image[::-1]
    if axes["horizontal_flip"]:
        image = image[:, ::-1]
    return image, axes


class SliceView(QWidget):
    """One 2D slice of the model's volume at the model's cursor."""

    cursor_picked = Signal(object)  # LPS point
    window_level_dragged = Signal(float, float)

    def __init__(self, plane: str, parent=None) -> None:
        super().__init__(parent)
        if plane not in PLANES:
            raise ValueError(f"plane must be one of {', '.join(PLANES)}, got {plane!r}")
        self.plane = plane
        self.setObjectName(f"slice-{plane}")
        self.setMinimumSize(160, 160)
        self.setSizePolicy(QSizePolicy.Expanding, QSizePolicy.Expanding)
        self.setMouseTracking(True)
        self.volume: Volume | None = None
        self.cursor = np.zeros(3)
        self.window, self.level = 400.0, 40.0
        self._image: QImage | None = None
        self._pixels: np.ndarray | None = None
        self.overlays: list[tuple[Volume, str]] = []  # fields on this volume's grid and their roles
        self._axes: dict = {}
        self._slice = 0
        self._hover = ""
        self._drag_start = None

    # -- model binding -----------------------------------------------------------------------------------
    def set_volume(self, volume: Volume, cursor, window: float, level: float) -> None:
        self.volume = volume
        self.window, self.level = window, level
        self.set_cursor(cursor, force=True)

    def set_cursor(self, cursor, *, force: bool = False) -> None:
        if self.volume is None:
            return
        self.cursor = np.asarray(cursor, dtype=float)
        axes = plane_axes(self.volume, self.plane)
        index = int(round(float(self.volume.world_to_index(self.cursor)[axes["slice_axis"]])))
        index = int(np.clip(index, 0, self.volume.dimensions[axes["slice_axis"]] - 1))
        if force or index != self._slice or self._pixels is None:
            self._slice = index
            self._pixels, self._axes = slice_image(self.volume, self.plane, index)
            self._rebuild_image()
        self.update()

    def set_overlays(self, overlays: list[tuple[Volume, str]]) -> None:
        """Fields to draw over the slices, each ``(volume on this view's grid, role)`` (see :mod:`app.overlays`)."""
        self.overlays = list(overlays)
        self._rebuild_image()
        self.update()

    def set_window_level(self, window: float, level: float) -> None:
        self.window, self.level = window, level
        self._rebuild_image()
        self.update()

    # -- drawing -----------------------------------------------------------------------------------------
    def _rebuild_image(self) -> None:
        if self._pixels is None:
            return
        low = self.level - self.window / 2
        grey = np.clip((self._pixels.astype(np.float32) - low) / self.window * 255.0, 0, 255).astype(np.uint8)
        grey = np.ascontiguousarray(grey)
        height, width = grey.shape
        if not self.overlays:
            self._grey = grey  # QImage does not own the buffer
            self._image = QImage(grey.data, width, height, width, QImage.Format_Grayscale8)
            return
        from app.overlays import overlay_rgba

        rgb = np.repeat(grey[..., None].astype(np.float32) / 255.0, 3, axis=2)
        for volume, role in self.overlays:
            values, _ = slice_image(volume, self.plane, self._slice)
            rgba = overlay_rgba(values, role)
            rgb = rgb * (1.0 - rgba[..., 3:4]) + rgba[..., :3] * rgba[..., 3:4]
        self._grey = np.ascontiguousarray(np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8))
        self._image = QImage(self._grey.data, width, height, 3 * width, QImage.Format_RGB888)

    def _pixel_size_mm(self) -> tuple[float, float]:
        spacing = self.volume.spacing
        return spacing[self._axes["horizontal"]], spacing[self._axes["vertical"]]

    def image_rect(self) -> QRectF:
        """Where the slice is drawn: centred, aspect kept in millimetres."""
        if self._pixels is None:
            return QRectF()
        rows, columns = self._pixels.shape
        sx, sy = self._pixel_size_mm()
        width_mm, height_mm = columns * sx, rows * sy
        scale = min(self.width() / width_mm, self.height() / height_mm)
        w, h = width_mm * scale, height_mm * scale
        return QRectF((self.width() - w) / 2, (self.height() - h) / 2, w, h)

    def _cursor_pixel(self) -> tuple[float, float]:
        """Continuous (column, row) of the cursor in the displayed slice."""
        ijk = self.volume.world_to_index(self.cursor)
        rows, columns = self._pixels.shape
        column = ijk[self._axes["horizontal"]]
        row = ijk[self._axes["vertical"]]
        if self._axes["horizontal_flip"]:
            column = columns - 1 - column
        if self._axes["vertical_flip"]:
            row = rows - 1 - row
        return column, row

    def _widget_to_world(self, x: float, y: float) -> np.ndarray | None:
        rect = self.image_rect()
        if rect.isEmpty() or not rect.contains(QPointF(x, y)):
            return None
        rows, columns = self._pixels.shape
        column = (x - rect.left()) / rect.width() * columns - 0.5
        row = (y - rect.top()) / rect.height() * rows - 0.5
        if self._axes["horizontal_flip"]:
            column = columns - 1 - column
        if self._axes["vertical_flip"]:
            row = rows - 1 - row
        ijk = np.empty(3)
        ijk[self._axes["slice_axis"]] = self._slice
        ijk[self._axes["horizontal"]] = column
        ijk[self._axes["vertical"]] = row
        return self.volume.index_to_world(ijk)

    def paintEvent(self, event) -> None:  # noqa: N802 - Qt override
        painter = QPainter(self)
        painter.fillRect(self.rect(), QColor(0, 0, 0))
        if self._image is None:
            painter.setPen(QColor(160, 160, 160))
            painter.drawText(self.rect(), Qt.AlignCenter, "No volume")
            return
        rect = self.image_rect()
        painter.setRenderHint(QPainter.SmoothPixmapTransform, False)
        painter.drawImage(rect, self._image)
        rows, columns = self._pixels.shape
        column, row = self._cursor_pixel()
        x = rect.left() + (column + 0.5) / columns * rect.width()
        y = rect.top() + (row + 0.5) / rows * rect.height()
        painter.setPen(QPen(QColor(255, 200, 0, 170), 1))
        painter.drawLine(QPointF(rect.left(), y), QPointF(rect.right(), y))
        painter.drawLine(QPointF(x, rect.top()), QPointF(x, rect.bottom()))
        painter.setPen(QColor(230, 230, 120))
        painter.setFont(QFont(painter.font().family(), 10, QFont.Bold))
        labels = self._axes["labels"]
        painter.drawText(self.rect().adjusted(4, 2, -4, -2), Qt.AlignHCenter | Qt.AlignTop, labels["top"])
        painter.drawText(self.rect().adjusted(4, 2, -4, -2), Qt.AlignHCenter | Qt.AlignBottom, labels["bottom"])
        painter.drawText(self.rect().adjusted(4, 2, -4, -2), Qt.AlignVCenter | Qt.AlignLeft, labels["left"])
        painter.drawText(self.rect().adjusted(4, 2, -4, -2), Qt.AlignVCenter | Qt.AlignRight, labels["right"])
        painter.setFont(QFont(painter.font().family(), 8))
        painter.setPen(QColor(200, 200, 200))
        axis = self._axes["slice_axis"]
        position = self.volume.index_to_world(self.volume.world_to_index(self.cursor))
        anatomical = ("x", "y", "z")[PLANES[self.plane][0]]
        text = (f"{self.plane.capitalize()} {self._slice + 1}/{self.volume.dimensions[axis]}  "
                f"{anatomical} = {position[PLANES[self.plane][0]]:.1f} mm\n"
                f"W {self.window:g} L {self.level:g} {self.volume.units_label}")
        if self._hover:
            text += f"\n{self._hover}"
        painter.drawText(self.rect().adjusted(6, 4, -6, -4), Qt.AlignLeft | Qt.AlignTop, text)
        painter.end()

    # -- mouse -----------------------------------------------------------------------------------------------
    def mousePressEvent(self, event) -> None:  # noqa: N802
        if self.volume is None:
            return
        if event.button() == Qt.LeftButton:
            self._pick(event.position() if hasattr(event, "position") else event.pos())
        elif event.button() == Qt.RightButton:
            point = event.position() if hasattr(event, "position") else event.pos()
            self._drag_start = (point.x(), point.y(), self.window, self.level)

    def mouseMoveEvent(self, event) -> None:  # noqa: N802
        if self.volume is None:
            return
        point = event.position() if hasattr(event, "position") else event.pos()
        if event.buttons() & Qt.LeftButton:
            self._pick(point)
        elif event.buttons() & Qt.RightButton and self._drag_start is not None:
            x0, y0, window, level = self._drag_start
            lo, hi = self.volume.value_range
            per_pixel = (hi - lo) / 1000.0
            new_window = max(1e-3, window + (point.x() - x0) * per_pixel * 2)
            new_level = level - (point.y() - y0) * per_pixel
            self.window_level_dragged.emit(new_window, new_level)
        world = self._widget_to_world(point.x(), point.y())
        if world is not None:
            ijk = np.rint(self.volume.world_to_index(world)).astype(int)
            ijk = np.clip(ijk, 0, np.asarray(self.volume.dimensions) - 1)
            value = self.volume.array[ijk[2], ijk[1], ijk[0]]
            self._hover = (f"({world[0]:.1f}, {world[1]:.1f}, {world[2]:.1f}) mm LPS: {value:g} "
                           f"{self.volume.units_label}")
        else:
            self._hover = ""
        self.update()

    def mouseReleaseEvent(self, event) -> None:  # noqa: N802
        self._drag_start = None

    def wheelEvent(self, event) -> None:  # noqa: N802
        if self.volume is None:
            return
        steps = 1 if event.angleDelta().y() > 0 else -1
        axis = self._axes["slice_axis"]
        index = int(np.clip(self._slice + steps, 0, self.volume.dimensions[axis] - 1))
        ijk = self.volume.world_to_index(self.cursor)
        ijk[axis] = index
        self.cursor_picked.emit(self.volume.index_to_world(ijk))

    def _pick(self, point) -> None:
        world = self._widget_to_world(point.x(), point.y())
        if world is not None:
            self.cursor_picked.emit(world)
