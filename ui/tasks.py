"""Long work off the GUI thread: tasks on a thread pool with progress, cancellation and results back on the GUI thread.

A task wraps a headless ``app`` function that accepts a ``progress`` callback. The callback forwards the fraction
to the GUI and raises :class:`OperationCancelled` once the user pressed Cancel, so the algorithm stops at its next
checkpoint. Results and errors arrive through the task's signals, on the GUI thread; workers never touch widgets,
plotters or actors.

Threads and lifetimes: a :class:`Task` is a QObject of the GUI thread, and only the GUI thread ever holds it. A pool
thread runs a plain :class:`_Work` (the function, its arguments and the task's cancel flag) and reports through the
runner's long-lived relay, queued to the GUI thread, where the runner re-emits the task's own signals and then lets
go of the task. So a task is never destroyed on a pool thread (a QObject must die on its own thread). The function,
its arguments and its result or error are handed back to the GUI thread the same way before the worker lets go of
them, so they too are released there, as soon as the task ends: they may hold VTK props whose OpenGL resources can
only be freed on the thread that renders.
"""

from __future__ import annotations

import itertools
import threading
import traceback
from typing import Any, Callable

from qtpy.QtCore import QObject, QThreadPool, Signal

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
        self._call: tuple | None = (function, args, kwargs)
        self._cancel = threading.Event()
        self.traceback = ""

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def is_cancelled(self) -> bool:
        return self._cancel.is_set()


class _Work:
    """What a pool thread runs for a task: its function and arguments and the task's cancel flag, but not the task
    itself. When the function has run, the function, its arguments and the outcome go into ``handed_back`` (read on
    the GUI thread) before the worker lets go of them."""

    def __init__(self, key: int, task: Task, relay: _Relay, handed_back: dict) -> None:
        if task._call is None:
            raise RuntimeError(f"the task {task.label!r} was started already")
        self.key = key
        self.label = task.label
        self.call, task._call = task._call, None
        self.cancel = task._cancel
        self.relay = relay
        self.handed_back = handed_back

    def _report(self, fraction: float) -> None:
        if self.cancel.is_set():
            raise OperationCancelled(f"{self.label} was cancelled")
        self.relay.progress.emit(self.key, float(fraction))

    def __call__(self) -> None:
        function, args, kwargs = self.call
        self.call = None
        result = error = None
        trace = ""
        try:
            if self.cancel.is_set():
                raise OperationCancelled(f"{self.label} was cancelled")
            result = function(*args, progress=self._report, **kwargs)
            if self.cancel.is_set():
                raise OperationCancelled(f"{self.label} was cancelled")
        except OperationCancelled as exc:
            outcome, error = "cancelled", exc
        except Exception as exc:  # every error reaches the user as a message, never as a crash
            outcome, error, trace = "failed", exc, traceback.format_exc()
        else:
            outcome = "finished"
        # Hand everything over before letting go of it here (a dict store is atomic under the GIL), so the last
        # reference to any of it, an error's traceback and its frames included, is dropped on the GUI thread.
        self.handed_back[self.key] = (outcome, result, error, trace, (function, args, kwargs))
        del function, args, kwargs, result, error
        self.relay.ended.emit(self.key)


class _Relay(QObject):
    """Carries the pool threads' reports, queued, to the runner on the GUI thread (tasks are named by their key)."""

    progress = Signal(object, float)
    ended = Signal(object)


class TaskRunner(QObject):
    """Starts tasks on a private thread pool and keeps track of the ones running (for the status bar)."""

    started = Signal(object)  # Task
    ended = Signal(object)  # Task

    def __init__(self, parent=None, max_threads: int = 2) -> None:
        super().__init__(parent)
        self.pool = QThreadPool(self)
        self.pool.setMaxThreadCount(max_threads)
        # Made after the pool: Qt deletes children in the order they were made, so when the runner goes the pool
        # first waits for its threads, and no worker can report to a relay that is gone.
        self._relay = _Relay(self)
        self._relay.progress.connect(self._progress)
        self._relay.ended.connect(self._ended)
        self._keys = itertools.count(1)
        self._tasks: dict[int, Task] = {}
        self._handed_back: dict[int, tuple] = {}

    def start(self, task: Task) -> Task:
        work = _Work(next(self._keys), task, self._relay, self._handed_back)
        self._tasks[work.key] = task
        self.started.emit(task)
        self.pool.start(work)
        return task

    @property
    def running(self) -> list[Task]:
        """The tasks started and not yet ended, oldest first."""
        return list(self._tasks.values())

    def _progress(self, key: int, fraction: float) -> None:
        self._tasks[key].progress.emit(fraction)  # queued from the worker, so always before its end

    def _ended(self, key: int) -> None:
        task = self._tasks[key]
        outcome, result, error, trace, _call = self._handed_back.pop(key)
        task.traceback = trace
        signal, arguments = {"finished": (task.finished, (result,)), "failed": (task.failed, (error,)),
                             "cancelled": (task.cancelled, ())}[outcome]
        signal.emit(*arguments)
        task.done.emit()
        del self._tasks[key]  # after the task's own signals: their slots still see it running
        self.ended.emit(task)

    def cancel_all(self) -> None:
        for task in self.running:
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
