"""Python's cyclic garbage collector, run on the GUI thread only, while the window's application lives.

CPython runs its cyclic collector in whichever thread happens to allocate past the collector's threshold. In the
workbench that is often a worker of :mod:`ui.tasks` (loading a volume, computing percentiles, meshing), and a
collection frees *every* unreachable cycle, not just the worker's own: the views, pipelines, VTK props and Qt
wrappers of a window or a view content that was let go a moment before. Their destructors then run on the worker:
a VTK object releasing OpenGL resources without the GL context, a Qt object dying outside its thread, which aborts
the process or corrupts it ("Fatal Python error: Aborted" while a worker computed percentiles and the GUI thread
waited). :class:`GuiThreadCollector` turns the automatic collector off and runs the same generational collections
from a timer on the GUI thread instead (the remedy pyqtgraph ships for the same Qt problem), so everything in a
cycle is finalised where the widgets and the GL context live. Objects freed by reference counting are not affected:
:mod:`ui.tasks` already hands a task's function, arguments and result back to the GUI thread before letting go.
"""

from __future__ import annotations

import gc

from qtpy.QtCore import QObject, QTimer
from qtpy.QtWidgets import QApplication

#: How often (ms) the GUI thread looks whether a collection is due.
INTERVAL_MS = 100


class GuiThreadCollector(QObject):
    """Disables automatic garbage collection and collects from a GUI-thread timer at CPython's own thresholds."""

    def __init__(self, parent: QObject, interval_ms: int = INTERVAL_MS) -> None:
        super().__init__(parent)
        self.thresholds = gc.get_threshold()
        self.collections = [0, 0, 0]
        self._timer = QTimer(self)
        self._timer.timeout.connect(self.check)
        self._timer.start(interval_ms)
        gc.disable()

    def check(self) -> None:
        """Collect the generations whose counts passed their thresholds, youngest first (CPython's rule)."""
        count0, count1, count2 = gc.get_count()
        if count0 > self.thresholds[0]:
            gc.collect(0)
            self.collections[0] += 1
            if count1 > self.thresholds[1]:
                gc.collect(1)
                self.collections[1] += 1
                if count2 > self.thresholds[2]:
                    gc.collect(2)
                    self.collections[2] += 1

    def stop(self) -> None:
        """Hand collection back to CPython (a last full collection first, on this thread)."""
        self._timer.stop()
        gc.collect()
        gc.enable()


def install(app: QApplication | None = None) -> GuiThreadCollector:
    """The collector of ``app`` (the running QApplication by default), made on first call; call it from the GUI
    thread. It lives as long as the application."""
    app = app or QApplication.instance()
    if app is None:
        raise RuntimeError("a QApplication must exist before the GUI-thread collector")
    collector = app.findChild(GuiThreadCollector)
    if collector is None:
        collector = GuiThreadCollector(app)
        app.aboutToQuit.connect(collector.stop)
    return collector
