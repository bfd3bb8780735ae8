"""``voxelscope modes``: the render modes, what each shows and the options it takes (from the mode registry)."""

from __future__ import annotations

from .common import print_json

NAME = "modes"
HELP = "list the render modes with their kind, description and options"
ORDER = 15


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args) -> int:
    from ..modes import modes

    registered = modes()
    if args.json:
        print_json({"modes": [mode.describe() for mode in registered]})
        return 0
    group = None
    for mode in registered:
        if mode.group != group:
            group = mode.group
            print(f"\n{group}")
        print(f"  {mode.name:32s} {mode.label} ({mode.origin}): {mode.description}")
        for option in mode.options:
            default = "automatic" if option.default is None else f"{option.default}{' ' + option.unit if option.unit else ''}"
            choices = f" [{'|'.join(map(str, option.allowed))}]" if option.choices else ""
            unit = f" ({option.unit})" if option.unit else ""
            print(f"  {'':32s}   {option.flag}{choices}{unit} (default {default}): {option.help}")
    return 0
