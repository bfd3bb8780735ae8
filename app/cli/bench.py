"""``voxelscope bench``: run a benchmark against VTK's built-ins; writes CSV files, plots and a JSON with the machine."""

from __future__ import annotations

import inspect
import sys
import time
from importlib import import_module
from pathlib import Path

NAME = "bench"
HELP = "run a benchmark against VTK's built-ins; writes CSV and plots"
ORDER = 60


def add_arguments(parser) -> None:
    from ..bench import BENCHMARKS

    parser.add_argument("name", choices=list(BENCHMARKS), help="benchmark")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.add_argument("--quick", action="store_true", help="a smaller run that finishes in a few minutes")
    parser.add_argument("--against", metavar="PATH", help="also measure another checkout of the project at PATH "
                        "(benchmarks that compare checkouts, e.g. compile)")


def run(args) -> int:
    from ..bench import BENCHMARKS

    module = import_module(BENCHMARKS[args.name])
    extra = {}
    if args.against is not None:
        if "against" not in inspect.signature(module.run).parameters:
            from .common import CommandError

            raise CommandError(f"the {args.name} benchmark measures one checkout only; --against applies to "
                               "benchmarks that compare checkouts (compile)")
        extra["against"] = args.against
    out_dir = Path(args.output).expanduser()
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    def progress(fraction: float) -> None:
        print(f"\r{args.name}: {100 * fraction:5.1f} %", end="", file=sys.stderr, flush=True)

    written = module.run(out_dir, quick=args.quick, progress=progress, **extra)
    print(file=sys.stderr)
    print(f"{args.name}: wrote {len(written)} files to {out_dir} in {time.perf_counter() - start:.1f} s")
    for path in written:
        print(f"  {path}")
    return 0
