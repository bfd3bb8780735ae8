"""What an operation is: scene items in, a new scene item out (a mesh from a volume, a mask from a mesh, a field from
two fields, tetrahedra from a volume), with typed options.

Render modes show an item; operations make one. Both are registered in one place each and both declare their
options with :class:`app.options.Option`, so the command line and the window offer the same settings. The window's
Operations menu lists every registered operation and builds its dialog from :attr:`Operation.inputs` and
:attr:`Operation.options`; commands such as ``voxelscope voxelise`` call :meth:`Operation.run` with the items they
loaded.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Mapping

from ..options import HasOptions, Option


@dataclass(frozen=True)
class Input:
    """One input of an operation: a name (``"mesh"``, ``"a"``, ``"like"``...), the item kinds it accepts, a help
    text, and whether it may be left out (``optional``, e.g. "the grid of this volume, else the options' grid")."""

    name: str
    kinds: tuple[str, ...]
    help: str = ""
    optional: bool = False

    def accepts(self, item) -> bool:
        return item.kind in self.kinds


@dataclass
class OperationResult:
    """The new item and the numbers to report (JSON-ready: seconds, counts, the rule used...)."""

    item: Any
    report: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Operation(HasOptions, ABC):
    """An operation. ``output`` is the kind of item it makes; ``group`` places it in the window's menu."""

    name: str
    label: str
    description: str
    inputs: tuple[Input, ...]
    output: str
    options: tuple[Option, ...] = ()
    group: str = "Surfaces"

    def resolve_options(self, values: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return self._resolve(f"operation {self.name!r}", values)

    def check_inputs(self, items: Mapping[str, Any]) -> None:
        """Every input given and of an accepted kind (ValueError naming the item otherwise)."""
        for spec in self.inputs:
            if items.get(spec.name) is None:
                if spec.optional:
                    continue
                raise ValueError(f"{self.label} needs an input '{spec.name}' ({' or '.join(spec.kinds)})")
            item = items[spec.name]
            if not spec.accepts(item):
                raise ValueError(f"{self.label}: '{spec.name}' must be a {' or '.join(spec.kinds)}, and "
                                 f"{item.name} is a {item.kind}")

    @abstractmethod
    def run(self, items: Mapping[str, Any], options: Mapping[str, Any], *, progress=None) -> OperationResult:
        """Make the new item from ``items`` (input name -> scene item) and resolved ``options``."""

    def describe(self) -> dict[str, Any]:
        return {
            "name": self.name, "label": self.label, "description": self.description, "output": self.output,
            "group": self.group, "inputs": [{"name": i.name, "kinds": list(i.kinds), "help": i.help, "optional": i.optional}
                       for i in self.inputs],
            "options": [option.describe() for option in self.options],
        }
