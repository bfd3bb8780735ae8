"""Long work off the GUI thread: tasks on a thread pool with progress, cancellation and results back on the GUI thread.

A task wraps a headless ``app`` function that accepts a ``progress`` callback. The callback forwards the fraction
to the GUI (queued signal) and raises :class:`OperationCancelled` once the user pressed Cancel, so the algorithm
stops at its next checkpoint. Results and errors arrive through signals connected before the task starts, on the
GUI thread; workers never touch widgets, plotters or actors.
"""

from __future__ import annotations

import threading
import traceback
from typing import Any, Callable

from qtpy.QtCore import QObject, QRunnable, QThreadPool, Signal

from algorithms.common.progress import OperationCancelled


class Task(QObject):
    """One unit of background work. Connect ``finished``/``failed``/``cancelled`` before :meth:`TaskRunner.start`."""

    progress = Signal(float)
    finished = Signal(object)
    failed = Signal(object)  # the exception
    cancelled = Signal()
    done = Signal()  # after any of the three above

    def __init__(self, label: str, function: Callable[..., Any], *args, **kwargs) -> None:
        super().__init__()
        self.label = label
        self._function = function
        self._args = args
        self._kwargs = kwargs
        self._cancel = threading.Event()
        self.traceback = ""

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def is_cancelled(self) -> bool:
        return self._cancel.is_set()

    def _report(self, fraction: float) -> None:
        if self._cancel.is_set():
            raise OperationCancelled(f"{self.label} was cancelled")
        self.progress.emit(float(fraction))

    def run(self) -> None:
        """Called on a pool thread."""
        try:
            if self._cancel.is_set():
                raise OperationCancelled(f"{self.label} was cancelled")
            result = self._function(*self._args, progress=self._report, **self._kwargs)
            if self._cancel.is_set():
                raise OperationCancelled(f"{self.label} was cancelled")
        except OperationCancelled:
            self.cancelled.emit()
        except Exception as exc:  # every error reaches the user as a message, never as a crash
            self.traceback = traceback.format_exc()
            self.failed.emit(exc)
        else:
            self.finished.emit(result)
        self.done.emit()


class _Runnable(QRunnable):
    def __init__(self, task: Task) -> None:
        super().__init__()
        self.task = task
        self.setAutoDelete(True)

    def run(self) -> None:
        self.task.run()


class TaskRunner(QObject):
    """Starts tasks on a private thread pool and keeps track of the ones running (for the status bar)."""

    started = Signal(object)  # Task
    ended = Signal(object)  # Task

    def __init__(self, parent=None, max_threads: int = 2) -> None:
        super().__init__(parent)
        self.pool = QThreadPool(self)
        self.pool.setMaxThreadCount(max_threads)
        self.running: list[Task] = []

    def start(self, task: Task) -> Task:
        self.running.append(task)
        task.done.connect(lambda task=task: self._ended(task))
        self.started.emit(task)
        self.pool.start(_Runnable(task))
        return task

    def _ended(self, task: Task) -> None:
        if task in self.running:
            self.running.remove(task)
        self.ended.emit(task)

    def cancel_all(self) -> None:
        for task in list(self.running):
            task.cancel()

    def wait(self, milliseconds: int = 30000) -> bool:
        return self.pool.waitForDone(milliseconds)


class QtJobRunner:
    """The view pipeline's job runner in the window (see :class:`app.pipeline.jobs.JobRunner`): each job becomes a
    :class:`Task` on the workbench's thread pool, so it shows in the status bar with progress and Cancel, and its
    callbacks arrive on the GUI thread."""

    def __init__(self, tasks: TaskRunner) -> None:
        self.tasks = tasks

    def submit(self, label: str, work, *, done, failed, cancelled) -> Task:
        task = Task(label, work)
        task.finished.connect(done)
        task.failed.connect(failed)
        task.cancelled.connect(cancelled)
        return self.tasks.start(task)
