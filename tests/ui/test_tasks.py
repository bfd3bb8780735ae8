"""The window's background tasks: results, errors, progress and Cancel arrive on the GUI thread, every task is
destroyed on the GUI thread as soon as it has ended, its inputs are let go of then, and signalling does not corrupt
the interpreter (PySide6 6.12.0 dropped a reference to ``True`` at every ``emit()``, which on Python 3.11 ends in a
crash once enough signals have been sent)."""

from __future__ import annotations

import sys
import threading
import time

import numpy as np
import pytest

from qtpy.QtCore import QObject, Signal

from ui.launch import signal_refcount_problem
from ui.tasks import Task, TaskRunner


class _Big:
    """An input or a result of a task that notes the thread it is let go of on."""

    def __init__(self, released_on: list) -> None:
        self.array = np.ones(1 << 16)
        self.released_on = released_on

    def __del__(self) -> None:
        self.released_on.append(threading.get_ident())


def test_emitting_signals_keeps_the_reference_count_of_true(qtbot):
    class Emitter(QObject):
        plain = Signal()
        number = Signal(float)

    emitter = Emitter()
    received = []
    emitter.number.connect(received.append)
    before = sys.getrefcount(True)
    for _ in range(1000):
        emitter.plain.emit()
        emitter.number.emit(0.5)
    lost = before - sys.getrefcount(True)
    assert len(received) == 1000
    # An affected binding loses 2000 references here; other threads may make or drop a few meanwhile.
    assert lost < 200, f"{lost} references to True lost in 2000 emits: this PySide6 build corrupts the interpreter"
    assert signal_refcount_problem() is None  # the window's start-up check agrees


def test_tasks_end_and_die_on_the_gui_thread_and_let_go_of_their_inputs_there(qtbot):
    """Tasks, their inputs and their results are released on the GUI thread as soon as the tasks end (they may
    hold VTK props, whose OpenGL resources only the rendering thread may free), without garbage collection."""
    runner = TaskRunner(max_threads=2)
    gui = threading.get_ident()
    worker_threads, destroyed_on, released_on, results = set(), [], [], []

    def work(big, index, progress=None):
        worker_threads.add(threading.get_ident())
        progress(0.5)
        if index % 4 == 3:
            raise ValueError(f"task {index} failed")
        return index, float(big.array.sum()), _Big(released_on)

    failures = []
    for index in range(12):
        task = Task(f"task {index}", work, _Big(released_on), index)
        task.finished.connect(lambda result: results.append(result[:2]))
        task.failed.connect(lambda exc: failures.append(str(exc)))
        task.destroyed.connect(lambda *_: destroyed_on.append(threading.get_ident()))
        runner.start(task)
        del task
    qtbot.waitUntil(lambda: len(results) + len(failures) == 12 and not runner.running, timeout=30_000)
    assert sorted(results) == [(index, float(1 << 16)) for index in range(12) if index % 4 != 3]
    assert sorted(failures) == sorted(f"task {index} failed" for index in (3, 7, 11))
    assert gui not in worker_threads
    qtbot.waitUntil(lambda: len(destroyed_on) == 12 and len(released_on) == 12 + 9, timeout=10_000)
    assert set(destroyed_on) == {gui} and set(released_on) == {gui}


def test_errors_progress_and_cancel_reach_the_gui_thread(qtbot):
    runner = TaskRunner(max_threads=2)
    gui = threading.get_ident()
    seen = {"progress": [], "failed": [], "cancelled": 0, "done": 0, "threads": set()}

    def note(key, value=None):
        seen["threads"].add(threading.get_ident())
        if key in ("cancelled", "done"):
            seen[key] += 1
        else:
            seen[key].append(value)

    def fails(progress=None):
        progress(0.25)
        raise ValueError("the volume has no samples: nothing to do")

    failing = Task("failing", fails)
    failing.progress.connect(lambda value: note("progress", value))
    failing.failed.connect(lambda exc: note("failed", exc))
    failing.done.connect(lambda: note("done"))
    with qtbot.waitSignal(failing.done, timeout=30_000):
        runner.start(failing)
    assert seen["progress"] == [0.25]
    assert [str(exc) for exc in seen["failed"]] == ["the volume has no samples: nothing to do"]
    assert "ValueError" in failing.traceback

    started = threading.Event()

    def runs_until_cancelled(progress=None):
        started.set()
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            progress(0.5)  # raises once Cancel was pressed
            time.sleep(0.005)
        return "not cancelled"

    long = Task("long", runs_until_cancelled)
    long.finished.connect(lambda value: note("failed", value))
    long.cancelled.connect(lambda: note("cancelled"))
    long.done.connect(lambda: note("done"))
    runner.start(long)
    assert runner.running == [long]
    assert started.wait(30.0)
    with qtbot.waitSignal(long.done, timeout=30_000):
        runner.cancel_all()
    assert seen["cancelled"] == 1 and seen["done"] == 2 and len(seen["failed"]) == 1
    assert runner.running == [] and seen["threads"] == {gui}


def test_a_task_runs_once(qtbot):
    runner = TaskRunner()
    task = Task("once", lambda progress=None: 1)
    with qtbot.waitSignal(task.done, timeout=30_000):
        runner.start(task)
    with pytest.raises(RuntimeError, match="started already"):
        runner.start(task)


class _Cycle:
    """Garbage in a reference cycle (as views, pipelines and props of a closed window are) that notes the thread
    the collector frees it on."""

    def __init__(self, freed_on: list) -> None:
        self.me = self
        self.freed_on = freed_on

    def __del__(self) -> None:
        self.freed_on.append(threading.current_thread().name)


def _allocate_in_a_worker(count: int = 200_000) -> list:
    """What a worker building a result does to the collector: many new container objects (returned, so they stay
    counted until the caller lets go of them)."""
    result = []

    def work():
        result.append([[index] for index in range(count)])

    thread = threading.Thread(target=work, name="worker")
    thread.start()
    thread.join()
    return result


def test_without_the_gui_thread_collector_a_worker_frees_the_window_s_cycles():
    """The hazard itself, with CPython's own collector: a worker that allocates runs the collection that frees
    garbage it never touched (here a cycle standing for a closed view's pipeline and its VTK props)."""
    import gc

    automatic = gc.isenabled()  # off once a window has installed the GUI-thread collector in this process
    gc.enable()
    try:
        freed_on: list[str] = []
        _Cycle(freed_on)
        _allocate_in_a_worker()
    finally:
        if not automatic:
            gc.disable()
    assert freed_on == ["worker"]


def test_the_window_frees_cycles_on_the_gui_thread_only(qtbot, window):
    """With the window's collector, the same worker frees nothing; the GUI thread's timer collects the cycle."""
    import gc

    from ui.gui_thread_gc import GuiThreadCollector

    assert not gc.isenabled() and window.findChild(GuiThreadCollector) is None  # the application owns it
    freed_on: list[str] = []
    _Cycle(freed_on)
    result = _allocate_in_a_worker()
    assert freed_on == []
    qtbot.waitUntil(lambda: bool(freed_on), timeout=10_000)
    assert freed_on == [threading.main_thread().name]
    del result


def test_a_window_is_deleted_c_plus_plus_side_first_and_the_next_one_is_unharmed(qtbot, make_window):
    """:func:`ui.lifetime.delete_now` deletes the window and every child widget (the views' interactors among them)
    while their Python wrappers are still held, so the collector later frees plain Python objects; a window made
    right after shows, resizes and draws."""
    from qtpy import shiboken

    from ui.lifetime import delete_now

    first = make_window()
    qtbot.waitUntil(lambda: all(_qt_surfaces(view.plotter) for view in first.views), timeout=10_000)
    held = [first, *first.views, *(view.plotter for view in first.views), *first.slice_views.values()]
    assert all(shiboken.isValid(widget) for widget in held)
    delete_now(first)
    assert not any(shiboken.isValid(widget) for widget in held)
    # No wrapper of a Qt object PySide cannot track (a QSurface is not a QObject) outlives the deletion: PySide would
    # hand it out for the next object allocated at its address.
    assert not any(_qt_surfaces(view.plotter) for view in first.views)
    delete_now(first)  # a second call leaves the deleted window alone
    del held, first
    second = make_window()
    second.resize(900, 700)
    qtbot.wait(50)
    assert all(shiboken.isValid(view.plotter) for view in second.views)
    frame = second.views[0].capture()
    assert frame.shape[0] > 0 and frame.shape[1] > 0


def _qt_surfaces(interactor) -> list:
    """The QSurface wrappers an interactor holds (pyvistaqt keeps its GL context's surface once it is drawn)."""
    from qtpy.QtCore import QObject
    from qtpy.QtGui import QSurface

    return [value for value in vars(interactor).values()
            if isinstance(value, QSurface) and not isinstance(value, QObject)]
