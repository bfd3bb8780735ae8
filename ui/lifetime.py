"""Deleting a window's C++ side at a known moment, while every Python wrapper of it is still alive.

A top-level window made from Python is owned by its Python wrapper: when that wrapper dies, Qt deletes the window
and with it every child widget. If the wrapper dies inside a cyclic garbage collection - the usual case for a window
whose signals are connected to its own bound methods - the collector has already cleared or freed some of the
children's wrappers (the views' ``QtInteractor`` among them) when Qt destroys their C++ objects, and PySide then
releases wrappers that are half gone. The process crashes later and elsewhere: ``scripts/stress-gui`` caught a new
window's ``QOpenGLWidget`` resize looking up its Python override on a stale wrapper (docs/testing.md).

:func:`delete_now` closes the window and deletes its C++ object straight away, from the GUI thread, while the caller
still holds the Python wrapper, so that PySide invalidates each child's wrapper in the order Qt destroys the children;
what the garbage collector frees afterwards is plain Python. The application calls it when its event loop ends, the
window tests after each test.
"""

from __future__ import annotations

import gc

from qtpy import shiboken
from qtpy.QtCore import QCoreApplication, QEvent
from qtpy.QtWidgets import QWidget


def delete_now(widget: QWidget) -> None:
    """Close ``widget`` (its ``closeEvent`` runs as for a user's close) and delete its C++ object now; then collect
    the Python garbage on this (the GUI) thread. A widget already deleted is left alone."""
    if not shiboken.isValid(widget):
        return
    widget.close()
    widget.deleteLater()
    # Deferred deletions posted outside any running event loop are delivered when asked for explicitly.
    QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
    gc.collect()
