"""A registry of named things (render modes, operations) filled by the modules of a package and by entry points.

Both registries of Voxelscope work the same way: every module of their package registers what it defines when it is
imported, the package's modules are all imported on first use, and installed packages may add their own through an
entry-point group. Adding a mode or an operation is therefore one new module (or one registration call), never an
edit elsewhere.
"""

from __future__ import annotations

import importlib
import pkgutil
from importlib.metadata import entry_points
from typing import Callable, Generic, Iterable, TypeVar

T = TypeVar("T")


class Registry(Generic[T]):
    """Named objects of one type. ``package`` is the package whose modules register them (all are imported on first
    use, except those named in ``skip``); ``group`` the entry-point group of plug-ins; ``what`` names the objects in
    messages ("render mode", "operation")."""

    def __init__(self, package: str, group: str, what: str, kind: type, *, skip: Iterable[str] = ()) -> None:
        self.package = package
        self.group = group
        self.what = what
        self.kind = kind
        self.skip = set(skip)
        self._items: dict[str, T] = {}
        self._loading = False
        self._loaded = False
        self.checks: list[Callable[[T, dict[str, T]], None]] = []

    def register(self, item: T) -> T:
        if not isinstance(item, self.kind):
            raise TypeError(f"register a {self.kind.__name__}, got {type(item).__name__}")
        if item.name in self._items:
            raise ValueError(f"a {self.what} named {item.name!r} is already registered")
        for check in self.checks:
            check(item, self._items)
        self._items[item.name] = item
        return item

    def unregister(self, name: str) -> None:
        self.load()
        self._items.pop(name, None)

    def get(self, name: str) -> T:
        self.load()
        try:
            return self._items[name]
        except KeyError:
            raise ValueError(f"unknown {self.what} {name!r}; choose one of {', '.join(self._items)}") from None

    def all(self) -> list[T]:
        self.load()
        return list(self._items.values())

    def load(self) -> None:
        """Import the package's modules and the entry points, once (re-entrant: a module being imported may look
        up what is already registered)."""
        if self._loaded or self._loading:
            return
        self._loading = True
        try:
            package = importlib.import_module(self.package)
            for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda info: info.name):
                if info.name not in self.skip and not info.name.startswith("_"):
                    importlib.import_module(f"{self.package}.{info.name}")

            for entry in entry_points(group=self.group):
                entry.load()
            self._loaded = True
        finally:
            self._loading = False
