"""Progress reporting and cancellation shared by every algorithm core.

A core that runs for long accepts ``progress=None``: a callable taking one float in ``[0, 1]``. The core calls it
between chunks of work (slabs, slices, image tiles; never from inside a numba kernel). The caller cancels by
raising :class:`OperationCancelled` from that callable; the core lets it propagate, so no partial result escapes.

The VTK filter wrappers forward the same calls to ``vtkAlgorithm.UpdateProgress`` and turn
``vtkAlgorithm.CheckAbort`` into :class:`OperationCancelled`, so VTK's progress events and abort work for our
filters exactly as for VTK's own.
"""

from __future__ import annotations

from typing import Callable, Optional

ProgressCallback = Optional[Callable[[float], None]]


class OperationCancelled(Exception):
    """The caller asked for the running operation to stop."""


def report(progress: ProgressCallback, fraction: float) -> None:
    """Call ``progress(fraction)`` if a callback was given (the callback may raise OperationCancelled)."""
    if progress is not None:
        progress(min(1.0, max(0.0, float(fraction))))


def scaled(progress: ProgressCallback, start: float, stop: float) -> ProgressCallback:
    """A callback mapping ``[0, 1]`` of a sub-task onto ``[start, stop]`` of the parent's progress."""
    if progress is None:
        return None

    def _sub(fraction: float) -> None:
        progress(start + (stop - start) * fraction)

    return _sub
