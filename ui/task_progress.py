"""The status bar's progress: the label of the newest running task, a bar and Cancel, following a
:class:`ui.tasks.TaskRunner`. The widgets stay in place, enabled or not, so the views never resize (and redraw)
because of them; the bar is repainted at most five times a second, since every repaint of the window also composes
the 3D views, which costs real time with software OpenGL."""

from __future__ import annotations

from qtpy.QtCore import QObject, QTimer, Signal
from qtpy.QtWidgets import QLabel, QProgressBar, QPushButton, QStatusBar

from .tasks import Task, TaskRunner


class TaskProgress(QObject):
    """Progress and Cancel for every task of ``tasks``, in ``status_bar``. ``idle`` is emitted when the last running
    task has ended."""

    idle = Signal()

    def __init__(self, tasks: TaskRunner, status_bar: QStatusBar, parent=None) -> None:
        super().__init__(parent)
        self.tasks = tasks
        self.label = QLabel("")
        self.bar = QProgressBar()
        self.bar.setRange(0, 100)
        self.bar.setTextVisible(False)
        self.bar.setMaximumWidth(220)
        self.bar.setEnabled(False)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setObjectName("cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(tasks.cancel_all)
        for widget in (self.label, self.bar, self.cancel_button):
            status_bar.addPermanentWidget(widget)
        self._fraction = 0.0
        self._timer = QTimer(self)
        self._timer.setInterval(200)
        self._timer.timeout.connect(self._show)
        tasks.started.connect(self._started)
        tasks.ended.connect(lambda task: self._update())

    @property
    def fraction(self) -> float:
        """The newest progress report of the running tasks (0 to 1)."""
        return self._fraction

    def _started(self, task: Task) -> None:
        task.progress.connect(self._note)
        self._update()

    def _note(self, fraction: float) -> None:
        self._fraction = fraction

    def _show(self) -> None:
        value = int(self._fraction * 100)
        if value != self.bar.value():
            self.bar.setValue(value)

    def _update(self) -> None:
        running = self.tasks.running
        busy = bool(running)
        self.bar.setEnabled(busy)
        self.cancel_button.setEnabled(busy)
        self.label.setText(running[-1].label if busy else "")
        if busy and not self._timer.isActive():
            self._fraction = 0.0
            self._timer.start()
        if not busy:
            self._timer.stop()
            self.bar.setValue(0)
            self.idle.emit()
