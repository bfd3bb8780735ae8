"""``voxelscope gui``: start the workbench, optionally scripted for demos and tests.

    voxelscope gui [PATH] [--labels LABELS [--color-table FILE]] [--layout 2x2] [--modes m1,m2,m3,m4]
                   [--preset NAME] [--iso VALUE] [--session FILE] [--enlarge VIEW] [--tool TOOL]
                   [--cut SPEC ... [--cut-mode remove|keep] [--cut-eval binary|distance]]
                   [--screenshot OUT.png] [--exit] [--timeout SECONDS]

PATH is a file, a DICOM folder, ``sample`` (the default: the CT phantom) or ``sample:mri``; ``--labels`` opens a
label volume (an atlas, a segmentation) over it; ``--session`` opens a saved session instead. With ``--screenshot``
the window is saved once every view and panel has finished its layout and every view has drawn its first
full-quality frame; ``--exit`` then closes it.
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
    parser.add_argument("--labels", metavar="LABELS", help="a label volume (atlas, segmentation) to draw over PATH, "
                                                          "or 'auto'/'yes' to treat PATH itself as labels")
    parser.add_argument("--color-table", metavar="FILE", help="names and colours of the labels (ITK-SNAP, 3D Slicer, "
                                                              "FreeSurfer, AAL or MRIcron file)")
    parser.add_argument("--session", metavar="FILE", help="open a saved session (File > Save session)")
    parser.add_argument("--enlarge", metavar="VIEW", help="show one view alone: axial, coronal, sagittal or 1-4")
    parser.add_argument("--cursor", type=float, nargs=3, metavar=("X", "Y", "Z"),
                        help="put the slice crosshair at this LPS point (mm)")
    parser.add_argument("--screenshot", metavar="OUT.png", help="save the whole window once every view has rendered")
    parser.add_argument("--exit", action="store_true", help="quit after the screenshot (or once every view rendered)")
    parser.add_argument("--timeout", type=float, default=600.0, metavar="SECONDS",
                        help="with --screenshot/--exit: give up after this long (default 600)")
    parser.add_argument("--force", action="store_true", help="replace an existing screenshot file")
    from app.cli.common import add_cut_arguments

    add_cut_arguments(parser)  # cut-away tools in every 3D view (issue 15)
    return parser


def signal_refcount_problem(emits: int = 64) -> str | None:
    """A one-line message if the Qt binding loses Python references when a signal is sent, else None. PySide6 6.12.0
    drops a reference to ``True`` at every ``emit()``; on Python 3.11, where ``True`` is an ordinary object, the
    window then crashes after some thousands of progress reports. Sending a few signals shows it at once."""
    from qtpy import API_NAME, PYQT_VERSION, PYSIDE_VERSION
    from qtpy.QtCore import QObject, Signal

    class Probe(QObject):
        ping = Signal()

    probe = Probe()
    before = sys.getrefcount(True)
    for _ in range(emits):
        probe.ping.emit()
    if before - sys.getrefcount(True) < emits // 2:
        return None
    return (f"{API_NAME} {PYSIDE_VERSION or PYQT_VERSION} loses a reference to Python's True at every Qt signal and "
            f"would crash the window; install a sound version: pip install 'PySide6-Essentials>=6.6,<6.12'")


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    modes = [m.strip() for m in args.modes.split(",")] if args.modes else []
    unknown = [m for m in modes if m not in mode_names()]
    if unknown:
        print(f"voxelscope: error: unknown mode(s) {', '.join(unknown)}; choose from {', '.join(mode_names())}",
              file=sys.stderr)
        return 2
    from pathlib import Path

    from app.cutaways import tools_from_specs

    try:
        tools = tools_from_specs(args.cut, mode=args.cut_mode)
    except ValueError as exc:
        print(f"voxelscope: error: {exc}", file=sys.stderr)
        return 2
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

    from .lifetime import delete_now
    from .main_window import MainWindow, application

    if args.session:
        from app.session import read_session

        try:
            read_session(args.session)
        except ValueError as exc:
            print(f"voxelscope: error: {exc}", file=sys.stderr)
            return 1
    if args.enlarge and args.enlarge not in ("axial", "coronal", "sagittal", "1", "2", "3", "4"):
        print(f"voxelscope: error: --enlarge takes axial, coronal, sagittal or a view number 1-4, got {args.enlarge}",
              file=sys.stderr)
        return 2
    configure_vtk()
    qt_app = application()
    problem = signal_refcount_problem()
    if problem:
        print(f"voxelscope: error: {problem}", file=sys.stderr)
        return 1
    window = MainWindow()
    window.ask_for_series = not (args.exit or args.screenshot)
    if tools:  # before the volume opens, so every view starts cut
        window.current_tool = 0
        window.model.cutaways.evaluation = args.cut_eval
        window.model.cutaways.set_tools(tools)
    if args.layout:
        window.model.set_layout(args.layout)
    for index, mode in enumerate(modes[:4]):
        window.model.set_view_mode(index, mode)
    window.show()
    outcome = {"status": 0}

    # Labels over PATH: "todo" until PATH is open, "loading" until they are, then "done".
    pending = {"labels": "todo" if args.labels and args.labels.lower() not in ("auto", "yes") else "done"}

    def apply_options(volume) -> None:
        if pending["labels"] == "todo":
            pending["labels"] = "loading"
            window.open_labels(resolve_path(args.labels), color_table=args.color_table)
            return
        pending["labels"] = "done"
        if args.preset:
            try:
                window.model.set_preset(args.preset)
            except ValueError:
                window.model.set_preset(args.preset, force=True)
                print(f"voxelscope: warning: {window.model.preset_warning()}", file=sys.stderr)
        if args.cursor:
            window.model.set_cursor(args.cursor)
        if args.enlarge:
            target = (window.slice_views[args.enlarge] if args.enlarge in window.slice_views
                      else window.views[int(args.enlarge) - 1])
            window.toggle_enlarged(target)
        if args.iso is not None:
            try:
                window.model.set_iso(args.iso)
            except ValueError as exc:
                print(f"voxelscope: error: {exc}", file=sys.stderr)
                outcome["status"] = 1
        if args.screenshot or args.exit:
            QTimer.singleShot(200, lambda: finish_once())  # the views may have been ready before the options

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

    if args.session:
        window.session_opened.connect(lambda path: apply_options(None))
    else:
        window.volume_loaded.connect(apply_options)
    window.load_failed.connect(failed)
    if args.exit:
        for view in window.views:
            view.failed.connect(failed)
    if args.screenshot or args.exit:
        # Wait until every view has drawn its final frame, then one more turn of the event loop to paint it.
        window.all_views_ready.connect(lambda: QTimer.singleShot(200, finish_once))
        done = {"fired": False, "busy": False}

        def finish_once() -> None:
            # Every view rendered: lay out every panel, paint, and check again (a layout change may resize views,
            # which then draw a new frame and announce readiness again).
            if done["fired"] or done["busy"] or pending["labels"] != "done" or (args.session and
                                                                                 window.model.base is None):
                return
            done["busy"] = True  # settling runs the event loop, which may call this again
            window.settle_layout()
            done["busy"] = False
            if not done["fired"] and window.fully_ready():
                done["fired"] = True
                finish()
            else:
                QTimer.singleShot(200, finish_once)

        QTimer.singleShot(int(args.timeout * 1000), timed_out)
    if args.session:
        window.open_session(args.session)
    else:
        labels = True if args.labels and args.labels.lower() in ("auto", "yes") else None
        window.open_path(resolve_path(args.path), series_uid=args.series, labels=labels)
    status = qt_app.exec()
    delete_now(window)  # the window's C++ side first, while its Python wrappers live (ui/lifetime.py)
    return outcome["status"] or int(status)
