"""Helpers of the issue-18 GUI tests: real mouse events at sub-pixel positions, volumes with known geometry."""

from __future__ import annotations

import numpy as np
from qtpy.QtCore import QEvent, QPoint, QPointF, Qt
from qtpy.QtGui import QMouseEvent, QWheelEvent
from qtpy.QtWidgets import QApplication

from app.io import save_volume
from app.volume import Volume


def mouse(widget, kind: str, position, button=Qt.LeftButton, buttons=None, modifiers=Qt.NoModifier) -> None:
    """Send a press/move/release/double-click mouse event at ``position`` (widget pixels, may be fractional)."""
    types = {"press": QEvent.MouseButtonPress, "move": QEvent.MouseMove, "release": QEvent.MouseButtonRelease,
             "double": QEvent.MouseButtonDblClick}
    local = QPointF(position)
    if buttons is None:
        buttons = Qt.NoButton if kind == "release" else button
    if kind == "move":
        button = Qt.NoButton
    event = QMouseEvent(types[kind], local, QPointF(widget.mapToGlobal(local)), button, buttons, modifiers)
    QApplication.sendEvent(widget, event)


def drag(widget, start, end, *, button=Qt.LeftButton, modifiers=Qt.NoModifier, steps: int = 8) -> None:
    mouse(widget, "press", start, button, modifiers=modifiers)
    for t in np.linspace(0, 1, steps + 1)[1:]:
        mouse(widget, "move", QPointF(start.x() + t * (end.x() - start.x()), start.y() + t * (end.y() - start.y())),
              button, buttons=button, modifiers=modifiers)
    mouse(widget, "release", end, button, modifiers=modifiers)


def wheel(widget, position, steps: int = 1, modifiers=Qt.NoModifier) -> None:
    local = QPointF(position)
    event = QWheelEvent(local, QPointF(widget.mapToGlobal(local)), QPoint(), QPoint(0, 120 * steps), Qt.NoButton,
                        modifiers, Qt.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)


def widget_image(widget) -> np.ndarray:
    """What the widget shows, ``(h, w, 3)`` uint8 (device-independent pixels)."""
    from qtpy.QtGui import QImage

    image = widget.grab().toImage().convertToFormat(QImage.Format_RGB888)
    width, height = image.width(), image.height()
    buffer = np.frombuffer(image.constBits(), dtype=np.uint8, count=image.sizeInBytes())
    return buffer.reshape(height, image.bytesPerLine())[:, : width * 3].reshape(height, width, 3).copy()


#: Centres (i, j, k) of the bright balls of :func:`marker_volume`, all on slice k = 10.
MARKERS = {"a": (20.0, 30.0, 10.0), "vertex": (50.0, 30.0, 10.0), "b": (62.0, 64.0, 10.0)}
MARKER_SPACING = (0.5, 0.5, 2.0)


def marker_volume() -> Volume:
    """Three bright balls (radius 2.5 mm) on one axial slice of a dark, slightly varying background, 0.5 mm pixels."""
    shape = (21, 90, 80)
    volume = Volume(np.zeros(shape, np.float32), spacing=MARKER_SPACING, origin=(-20.0, -22.0, 40.0), modality="MR")
    k, j, i = np.mgrid[0:shape[0], 0:shape[1], 0:shape[2]]
    world = volume.index_to_world(np.stack([i, j, k], axis=-1))
    values = 10.0 + 0.05 * i + 0.03 * j
    for centre in MARKERS.values():
        distance = np.linalg.norm(world - volume.index_to_world(centre), axis=-1)
        values = np.where(distance <= 2.5, 1000.0, values)
    volume.array = values.astype(np.float32)
    return volume


def marker_file(tmp_path) -> str:
    return save_volume(marker_volume(), tmp_path / "markers.nii.gz")
