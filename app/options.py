"""Typed options: what the command line offers as ``--flag`` and the window's options panels as widgets.

Render modes (:mod:`app.modes`) and operations (:mod:`app.operations`) declare their options with :class:`Option`;
the command line builds its flags from the declarations and the window builds its panels from them, so every option
can be set in both and is checked in one place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence


_TYPES = {"int": int, "float": float, "str": str, "bool": bool}


@dataclass(frozen=True)
class Option:
    """One typed option of a mode: what the command line offers as ``--name`` and the options panel as a widget.

    ``type`` is ``"int"``, ``"float"``, ``"str"`` or ``"bool"``. ``default`` None means "automatic" (the mode decides,
    for example one slice per voxel); the help text says what automatic means. ``unit`` is shown with the value
    ("mm", "degrees", "HU", "" for counts and names).
    """

    name: str
    type: str
    default: Any
    help: str
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[Any, ...] | Callable[[], tuple[Any, ...]] | None = None

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"option names are Python identifiers, got {self.name!r}")
        if self.type not in _TYPES:
            raise ValueError(f"option {self.name!r}: type must be one of {', '.join(_TYPES)}, got {self.type!r}")
        if self.default is not None:
            object.__setattr__(self, "default", self.validate(self.default))

    @property
    def allowed(self) -> tuple[Any, ...] | None:
        """The allowed values (``choices`` may be a function, evaluated now: e.g. the registered surface modes)."""
        return tuple(self.choices()) if callable(self.choices) else self.choices

    @property
    def flag(self) -> str:
        """The command-line flag: ``light_samples`` -> ``--light-samples``."""
        return "--" + self.name.replace("_", "-")

    @property
    def label(self) -> str:
        """A label for the options panel: ``light_samples`` -> ``Light samples`` (with the unit)."""
        text = self.name.replace("_", " ").capitalize()
        return f"{text} ({self.unit})" if self.unit else text

    @property
    def python_type(self) -> type:
        return _TYPES[self.type]

    def validate(self, value: Any) -> Any:
        """``value`` converted to the option's type and checked; a ValueError says what is allowed."""
        if value is None:
            return None
        kind = self.python_type
        try:
            if kind is bool:
                if isinstance(value, str):
                    if value.lower() not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                        raise ValueError
                    converted: Any = value.lower() in ("true", "1", "yes", "on")
                else:
                    converted = bool(value)
            elif kind is int:
                if isinstance(value, bool) or float(value) != int(float(value)):
                    raise ValueError
                converted = int(float(value))
            elif kind is float:
                converted = float(value)
                if not math.isfinite(converted):
                    raise ValueError
            else:
                converted = str(value)
        except (TypeError, ValueError):
            raise ValueError(f"{self.flag} must be {self._what()}, got {value!r}") from None
        allowed = self.allowed
        if allowed is not None and converted not in allowed:
            raise ValueError(f"{self.flag} must be one of {', '.join(map(str, allowed))}, got {value!r}")
        if self.minimum is not None and converted < self.minimum:
            raise ValueError(f"{self.flag} must be at least {self.minimum:g}{self._unit()}, got {value!r}")
        if self.maximum is not None and converted > self.maximum:
            raise ValueError(f"{self.flag} must be at most {self.maximum:g}{self._unit()}, got {value!r}")
        return converted

    def _unit(self) -> str:
        return f" {self.unit}" if self.unit else ""

    def _what(self) -> str:
        return {"int": "a whole number", "float": "a number", "str": "text", "bool": "true or false"}[self.type] + (
            f" in {self.unit}" if self.unit else "")

    def describe(self) -> dict[str, Any]:
        """JSON-ready description (``voxelscope modes --json``)."""
        return {
            "name": self.name, "flag": self.flag, "type": self.type, "default": self.default, "unit": self.unit,
            "minimum": self.minimum, "maximum": self.maximum,
            "choices": list(self.allowed) if self.choices is not None else None, "help": self.help,
        }

    def same_as(self, other: "Option") -> bool:
        """Two modes may share an option name only with the same meaning (one command-line flag serves both)."""
        return (self.type, self.unit, self.allowed) == (other.type, other.unit, other.allowed)


def resolve_options(owner: str, declared: Sequence[Option], values: Mapping[str, Any] | None) -> dict[str, Any]:
    """Every declared option with ``values`` applied over the defaults, validated.

    A name that is not declared is a ValueError naming ``owner`` (e.g. "mode 'raymarch'") and listing its options.
    """
    values = dict(values or {})
    known = {option.name for option in declared}
    unknown = sorted(set(values) - known)
    if unknown:
        flags = ", ".join("--" + name.replace("_", "-") for name in unknown)
        have = ", ".join(option.flag for option in declared) or "none"
        raise ValueError(f"{flags} does not apply to {owner} (its options: {have})")
    return {option.name: option.validate(values[option.name]) if option.name in values else option.default
            for option in declared}


class HasOptions:
    """What modes and operations share about their declared ``options``: lookup by name and resolution."""

    options: tuple[Option, ...] = ()

    def option(self, name: str) -> Option:
        for option in self.options:
            if option.name == name:
                return option
        raise KeyError(name)

    def check_options(self, options: Mapping[str, Any]) -> None:
        """Cross-option rules (``--slices`` and ``--slice-distance`` together, ...); ValueError if broken."""

    def _resolve(self, owner: str, values: Mapping[str, Any] | None) -> dict[str, Any]:
        resolved = resolve_options(owner, self.options, values)
        self.check_options(resolved)
        return resolved
