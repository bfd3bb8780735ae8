"""Undo and redo through Qt's undo stack: each :class:`app.workbench.Change` the model announces becomes a
:class:`QUndoCommand` whose undo and redo call back into the model (the state logic stays in ``app``)."""

from __future__ import annotations

import zlib

from qtpy.QtGui import QUndoCommand, QUndoStack


class ModelCommand(QUndoCommand):
    def __init__(self, change) -> None:
        super().__init__(change.label)
        self.change = change
        self._first = True
        self._undo = change.undo
        self.closed = False  # set when the drag that made it ended: the next change is a new undo step

    def id(self) -> int:  # noqa: A003 - Qt's name
        return zlib.crc32(self.change.merge_key.encode()) & 0x7FFFFFFF if self.change.merge_key else -1

    def mergeWith(self, other) -> bool:  # noqa: N802 - Qt override
        if self.closed or other.change.merge_key != self.change.merge_key:
            return False
        self.change = other.change  # redo goes to the newest state, undo still to the state before the drag
        return True

    def redo(self) -> None:
        if self._first:  # pushed after the model already made the change
            self._first = False
            return
        self.change.redo()

    def undo(self) -> None:
        self._undo()


def close_merging(stack: QUndoStack) -> None:
    """A drag ended: the last command takes no more changes of that drag's kind."""
    if stack.index() > 0:
        command = stack.command(stack.index() - 1)
        if isinstance(command, ModelCommand):
            command.closed = True


def bind_undo_stack(model, parent) -> QUndoStack:
    """A QUndoStack fed by ``model.undoable`` and cleared by ``model.history_cleared``."""
    stack = QUndoStack(parent)
    model.undoable.connect(lambda change: stack.push(ModelCommand(change)))
    model.history_cleared.connect(stack.clear)
    return stack
