"""``voxelscope gui``: start the desktop workbench (the default without a command). Its options belong to the front
end ('voxelscope gui --help'), found through the ``voxelscope.frontends`` entry point so this layer never imports Qt."""

from __future__ import annotations

from typing import Sequence

from .common import CommandError

NAME = "gui"
HELP = "start the desktop workbench (also the default); 'voxelscope gui --help' for its options"
ORDER = 0
ADD_HELP = False


def add_arguments(parser) -> None:
    """The front end parses its own arguments (``main`` hands them over before this parser sees them)."""


def run(args) -> int:
    return start_frontend([])


def start_frontend(argv: Sequence[str]) -> int:
    from importlib.metadata import entry_points

    frontends = [ep for ep in entry_points(group="voxelscope.frontends") if ep.name == "gui"]
    if not frontends:
        raise CommandError("the desktop front end is not installed; install Voxelscope with its 'ui' package")
    return int(frontends[0].load()(list(argv)) or 0)
