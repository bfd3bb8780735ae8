"""The operation registry: every way Voxelscope makes a new scene item from others, by name.

Operations are registered with :func:`register_operation` by the modules of this package (one per family, all
loaded on first use) and by installed packages through the ``voxelscope.operations`` entry-point group. The window's
Operations menu and the commands that run them read this registry only.
"""

from __future__ import annotations

from ..registry import Registry
from .base import Input, Operation, OperationResult

__all__ = ["Input", "Operation", "OperationResult", "register_operation", "get_operation", "operations",
           "unregister_operation"]

_REGISTRY: Registry[Operation] = Registry(__name__, "voxelscope.operations", "operation", Operation, skip={"base"})


def register_operation(operation: Operation) -> Operation:
    return _REGISTRY.register(operation)


def unregister_operation(name: str) -> None:
    _REGISTRY.unregister(name)


def get_operation(name: str) -> Operation:
    return _REGISTRY.get(name)


def operations() -> list[Operation]:
    return _REGISTRY.all()
