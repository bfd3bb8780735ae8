"""The render-mode registry: every way Voxelscope can show a scene item, by name. The one extension point.

A mode is a :class:`~app.modes.base.Mode` registered with :func:`register_mode`. The modules of this package
register the built-in modes, one module per family (:mod:`.surfaces`, :mod:`.volume_mappers`, :mod:`.renderers`,
:mod:`.comparisons`, :mod:`.meshes`, ...); every module here is loaded on first use, and installed packages may add
modes through the ``voxelscope.modes`` entry-point group (each entry point is a module imported for its
registrations). The command line (``voxelscope modes``, ``render --mode``, the option flags), the view pipeline and
the window's mode chooser and options panel all read this registry and nothing else, so adding a mode changes no
other file.
"""

from __future__ import annotations

from typing import Iterable

from ..registry import Registry
from .base import GROUPS, INPUT_KINDS, OUTPUT_KINDS, Capabilities, Mode, Option

__all__ = [
    "Capabilities", "Mode", "Option", "GROUPS", "INPUT_KINDS", "OUTPUT_KINDS", "register_mode", "unregister_mode",
    "get_mode", "mode_names", "modes", "all_options", "modes_for",
]

def _one_meaning_per_option(mode: Mode, registered: dict[str, Mode]) -> None:
    """An option name shared by two modes must mean the same (the command line makes one flag of it)."""
    shared = {option.name: option for existing in registered.values() for option in existing.options}
    for option in mode.options:
        other = shared.get(option.name)
        if other is not None and not other.same_as(option):
            raise ValueError(f"mode {mode.name!r}: option {option.flag} clashes with the option of the same name of "
                             f"another mode ({other.type}, {other.unit or 'no unit'}); choose another name")


_REGISTRY: Registry[Mode] = Registry(__name__, "voxelscope.modes", "render mode", Mode, skip={"base"})
_REGISTRY.checks.append(_one_meaning_per_option)


def register_mode(mode: Mode) -> Mode:
    """Add a mode. Names are unique; an option name shared with another mode must mean the same (one flag)."""
    return _REGISTRY.register(mode)


def unregister_mode(name: str) -> None:
    """Remove a mode (tests and plug-ins that register modes at run time clean up with this)."""
    _REGISTRY.unregister(name)


def get_mode(name: str) -> Mode:
    """The mode called ``name``; a ValueError lists the choices otherwise."""
    return _REGISTRY.get(name)


def modes() -> list[Mode]:
    """Every registered mode, grouped as the window's chooser shows them (by :data:`GROUPS`, then registration)."""
    order = {group: index for index, group in enumerate(GROUPS)}
    return sorted(_REGISTRY.all(), key=lambda mode: order[mode.group])


def mode_names(*, input: str | None = None, output: str | Iterable[str] | None = None) -> list[str]:
    """Registered mode names, optionally only those taking ``input`` (an item kind) or giving ``output``."""
    outputs = {output} if isinstance(output, str) else set(output) if output is not None else None
    return [mode.name for mode in modes()
            if (input is None or mode.input == input) and (outputs is None or mode.output in outputs)]


def modes_for(item) -> list[Mode]:
    """The modes that can show a scene item (volumes and fields share the gridded modes)."""
    gridded = hasattr(item, "volume")
    return [mode for mode in modes() if mode.input == item.kind or (mode.input == "volume" and gridded)]


def all_options() -> list:
    """Every option of every mode, once per name (the command line makes one flag of each)."""
    seen = {}
    for mode in modes():
        for option in mode.options:
            seen.setdefault(option.name, option)
    return list(seen.values())
