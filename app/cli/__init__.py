"""The ``voxelscope`` command line.

Each subcommand is a module of this package with ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args)``;
every module here is a command (discovered, not listed), so a new command is one new file. The commands use the same
headless logic as the window (``app.io``, ``app.scene``, ``app.pipeline``, ``app.meshing``, ``app.bench``); render
modes and their options come from the mode registry (``app.modes``), so a new mode needs no change here.

Errors end the program with a non-zero exit status and one clear line on stderr; ``--debug`` shows the traceback.
The desktop front end is found through the ``voxelscope.frontends`` entry point (provided by the ``ui`` package), so
this Qt-free layer never imports the user interface.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from typing import Sequence

from .common import EXIT_ERROR, CommandError

__all__ = ["main", "build_parser", "CommandError"]

_NOT_COMMANDS = {"common", "options"}


def _command_modules() -> list:
    modules = []
    for info in pkgutil.iter_modules(__path__):
        if info.name in _NOT_COMMANDS or info.name.startswith("_"):
            continue
        modules.append(importlib.import_module(f"{__name__}.{info.name}"))
    return sorted(modules, key=lambda module: (getattr(module, "ORDER", 100), module.NAME))


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="voxelscope",
        description="Voxelscope: look at medical and scientific volumes and meshes in several render modes, cut into "
                    "them, export meshes. Without a command, starts the desktop workbench.",
    )
    parser.add_argument("--version", action="version", version=f"Voxelscope {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in _command_modules():
        sub = commands.add_parser(module.NAME, help=module.HELP, description=module.HELP,
                                  add_help=getattr(module, "ADD_HELP", True))
        module.add_arguments(sub)
        sub.set_defaults(handler=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    if debug:
        argv.remove("--debug")
    # Everything after "gui" (or no command at all) belongs to the front end's own parser.
    if not argv or argv[0] == "gui" or (argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version")):
        from .gui import start_frontend

        extra = argv[1:] if argv and argv[0] == "gui" else argv
        return _run(lambda: start_frontend(extra), debug)
    parser = build_parser()
    args = parser.parse_args(argv)
    return _run(lambda: args.handler(args), debug)


def _run(action, debug: bool) -> int:
    from algorithms.common.progress import OperationCancelled
    from algorithms.common.vtk_bridge import VTKError

    from ..io.errors import VolumeReadError, VolumeWriteError
    from ..vtk_setup import configure_vtk

    configure_vtk()
    try:
        return int(action() or 0)
    except KeyboardInterrupt:
        print("voxelscope: interrupted", file=sys.stderr)
        return 130
    except (CommandError, VolumeReadError, VolumeWriteError, ValueError, KeyError, OperationCancelled, VTKError,
            OSError, MemoryError) as exc:
        if debug:
            raise
        print(f"voxelscope: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_ERROR
    except Exception as exc:  # a bug of ours: still one line, and the way to the details
        if debug:
            raise
        print(f"voxelscope: error: internal error ({type(exc).__name__}: {_one_line(exc)}); run the command again "
              "with --debug for the traceback and report it", file=sys.stderr)
        return EXIT_ERROR


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.filename:
        message = f"{exc.filename}: {exc.strerror}"
    elif isinstance(exc, MemoryError):
        message = "not enough memory for this operation; try a smaller volume, grid or image"
    elif isinstance(exc, KeyError) and exc.args:
        message = str(exc.args[0])
    else:
        message = str(exc) or type(exc).__name__
    return " ".join(message.split())
