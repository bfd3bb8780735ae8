"""A minimal, Qt-free event: the model objects of ``app`` announce changes through these.

Widgets connect callbacks and write back through the model's setters (napari's layer events and 3D Slicer's
parameter nodes work the same way), so the model stays usable, and testable, without a window.
"""

from __future__ import annotations

import weakref
from typing import Any, Callable


class Signal:
    """Callbacks called in connection order with the emitted arguments.

    Bound methods are held weakly, so a closed widget that forgot to disconnect is simply dropped.
    """

    def __init__(self) -> None:
        self._slots: list[Any] = []
        self._blocked = 0

    def connect(self, callback: Callable[..., Any]) -> Callable[..., Any]:
        if hasattr(callback, "__self__") and hasattr(callback, "__func__"):
            reference: Any = weakref.WeakMethod(callback)
        else:
            reference = lambda callback=callback: callback  # noqa: E731 - strong reference to plain functions
        self._slots.append(reference)
        return callback

    def disconnect(self, callback: Callable[..., Any]) -> None:
        self._slots = [ref for ref in self._slots if ref() not in (None, callback)]

    def emit(self, *args: Any) -> None:
        if self._blocked:
            return
        alive = []
        for reference in list(self._slots):
            callback = reference()
            if callback is None:
                continue
            alive.append(reference)
            callback(*args)
        self._slots = [ref for ref in self._slots if ref in alive or ref() is not None]

    def blocked(self):
        """Context manager that silences the signal (for batched updates)."""
        signal = self

        class _Block:
            def __enter__(self):
                signal._blocked += 1

            def __exit__(self, *exc):
                signal._blocked -= 1

        return _Block()
