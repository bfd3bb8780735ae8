"""``voxelscope bench``: run a benchmark against VTK's built-ins; writes CSV files, plots and a JSON with the machine."""

from __future__ import annotations

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


def run(args) -> int:
    from ..bench import BENCHMARKS

    module = import_module(BENCHMARKS[args.name])
    out_dir = Path(args.output).expanduser()
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    def progress(fraction: float) -> None:
        print(f"\r{args.name}: {100 * fraction:5.1f} %", end="", file=sys.stderr, flush=True)

    written = module.run(out_dir, quick=args.quick, progress=progress)
    print(file=sys.stderr)
    print(f"{args.name}: wrote {len(written)} files to {out_dir} in {time.perf_counter() - start:.1f} s")
    for path in written:
        print(f"  {path}")
    return 0
