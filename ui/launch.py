"""``voxelscope gui``: start the workbench, optionally scripted for demos and tests.

    voxelscope gui [PATH] [--layout 2x2] [--modes m1,m2,m3,m4] [--preset NAME] [--iso VALUE]
                   [--screenshot OUT.png] [--exit] [--timeout SECONDS]

PATH is a file, a DICOM folder, ``sample`` (the default: the CT phantom) or ``sample:mri``. With ``--screenshot``
the window is saved as soon as every view has rendered at full quality; ``--exit`` then closes it.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Sequence

from app.modes import mode_names
from app.transfer import preset_names
from app.workbench import LAYOUTS


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="voxelscope gui", description="Start the Voxelscope workbench.")
    parser.add_argument("path", nargs="?", default="sample",
                        help="volume file or DICOM folder to open (default: 'sample', the bundled CT phantom)")
    parser.add_argument("--layout", choices=list(LAYOUTS), help="view grid")
    parser.add_argument("--modes", help=f"comma-separated render modes of the views; choices: {', '.join(mode_names())}")
    parser.add_argument("--preset", choices=preset_names(), help="transfer function preset")
    parser.add_argument("--iso", type=float, help="isovalue of the surface views (volume units)")
    parser.add_argument("--series", metavar="UID", help="DICOM series to open")
    parser.add_argument("--screenshot", metavar="OUT.png", help="save the whole window once every view has rendered")
    parser.add_argument("--exit", action="store_true", help="quit after the screenshot (or once every view rendered)")
    parser.add_argument("--timeout", type=float, default=600.0, metavar="SECONDS",
                        help="with --screenshot/--exit: give up after this long (default 600)")
    parser.add_argument("--force", action="store_true", help="replace an existing screenshot file")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    modes = [m.strip() for m in args.modes.split(",")] if args.modes else []
    unknown = [m for m in modes if m not in mode_names()]
    if unknown:
        print(f"voxelscope: error: unknown mode(s) {', '.join(unknown)}; choose from {', '.join(mode_names())}",
              file=sys.stderr)
        return 2
    from pathlib import Path

    if args.screenshot and Path(args.screenshot).exists() and not args.force:
        print(f"voxelscope: error: {args.screenshot} already exists; choose another name or add --force",
              file=sys.stderr)
        return 1

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                                                 or os.environ.get("QT_QPA_PLATFORM")):
        print("voxelscope: error: no display to open the window on (DISPLAY is not set). Run it on a desktop, "
              "through 'ssh -X', or under a virtual X server: xvfb-run voxelscope gui ...", file=sys.stderr)
        return 1
    from qtpy.QtCore import QTimer

    from app.samples import resolve_path
    from app.vtk_setup import configure_vtk

    from .main_window import MainWindow, application

    configure_vtk()
    qt_app = application()
    window = MainWindow()
    window.ask_for_series = not (args.exit or args.screenshot)
    if args.layout:
        window.model.set_layout(args.layout)
    for index, mode in enumerate(modes[:4]):
        window.model.set_view_mode(index, mode)
    window.show()
    outcome = {"status": 0}

    def apply_options(volume) -> None:
        if args.preset:
            window.model.set_preset(args.preset)
        if args.iso is not None:
            try:
                window.model.set_iso(args.iso)
            except ValueError as exc:
                print(f"voxelscope: error: {exc}", file=sys.stderr)
                outcome["status"] = 1

    def finish() -> None:
        if args.screenshot:
            from app.pipeline import write_png

            write_png(window.grab_window(), args.screenshot, overwrite=args.force)
            print(f"Saved {args.screenshot}")
        if args.exit:
            window.close()
            qt_app.quit()

    def failed(message: str) -> None:
        print(f"voxelscope: error: {message}", file=sys.stderr)
        outcome["status"] = 1
        if args.exit:
            window.close()
            qt_app.quit()

    def timed_out() -> None:
        print(f"voxelscope: error: the views did not finish rendering within {args.timeout:g} s", file=sys.stderr)
        outcome["status"] = 1
        if args.screenshot:
            finish()
        elif args.exit:
            window.close()
            qt_app.quit()

    window.volume_loaded.connect(apply_options)
    window.load_failed.connect(failed)
    if args.exit:
        for view in window.views:
            view.failed.connect(failed)
    if args.screenshot or args.exit:
        # Wait until every view has drawn its final frame, then one more turn of the event loop to paint it.
        window.all_views_ready.connect(lambda: QTimer.singleShot(200, finish_once))
        done = {"fired": False}

        def finish_once() -> None:
            if not done["fired"] and window.views_ready():
                done["fired"] = True
                finish()

        QTimer.singleShot(int(args.timeout * 1000), timed_out)
    window.open_path(resolve_path(args.path), series_uid=args.series)
    status = qt_app.exec()
    return outcome["status"] or int(status)
