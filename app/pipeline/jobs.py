"""How a view pipeline runs its long work: through a job runner the host provides.

The pipeline never decides where work runs. The window gives it a runner backed by a thread pool (results delivered
on the GUI thread, see ``ui/tasks.py``); the command line and the tests give it :class:`ImmediateRunner`, which runs
each job at once on the calling thread. Either way a job is a function ``work(progress=None)`` that may call
``progress(fraction)``; raising :class:`~algorithms.common.progress.OperationCancelled` from that callback cancels it.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol

from algorithms.common.progress import OperationCancelled, ProgressCallback

Work = Callable[..., Any]  # work(progress=None) -> result


class Job(Protocol):
    """A submitted job: it can be cancelled (its callbacks are then never called with a result)."""

    def cancel(self) -> None: ...


class JobRunner(Protocol):
    """Runs ``work`` and calls exactly one of ``done(result)``, ``failed(exception)`` or ``cancelled()``.

    The callbacks run on the thread that owns the view (the GUI thread in the window).
    """

    def submit(self, label: str, work: Work, *, done: Callable[[Any], None],
               failed: Callable[[Exception], None], cancelled: Callable[[], None]) -> Job: ...


class _Finished:
    """The handle of a job that ran to its end before ``submit`` returned."""

    def cancel(self) -> None:
        pass


class ImmediateRunner:
    """Runs every job at once on the calling thread: the command line's and the tests' runner.

    ``progress`` (optional) receives each job's fractions. With ``raise_errors`` (the default) a failing job's
    exception propagates out of ``submit`` (and so out of the pipeline call that started it), which is what a
    command line wants; otherwise it goes to the job's ``failed`` callback like in the window.
    """

    def __init__(self, progress: ProgressCallback = None, *, raise_errors: bool = True) -> None:
        self.progress = progress
        self.raise_errors = raise_errors

    def submit(self, label: str, work: Work, *, done: Callable[[Any], None],
               failed: Callable[[Exception], None], cancelled: Callable[[], None]) -> Job:
        try:
            result = work(progress=self.progress)
        except OperationCancelled:
            cancelled()
            if self.raise_errors:
                raise
            return _Finished()
        except Exception as exc:
            if self.raise_errors:
                raise
            failed(exc)
            return _Finished()
        done(result)
        return _Finished()
