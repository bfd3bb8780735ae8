"""A fixed-seed generator of damaged volume files, and a harness that checks the readers' contract on them.

The contract (issue 20): a damaged file gives a one-line :class:`VolumeReadError` naming the file and a non-zero
exit; never a traceback, a crash (abort, segfault), a hang, a runaway allocation, or damaged data loaded silently.

Variants, per base file (DICOM series, NIfTI .nii / .nii.gz / NIfTI-2, NRRD .nrrd raw and gzip, .nhdr + raw /
gzip, MetaImage .mha / .mhd + .zraw / .raw, VTI appended raw / base64 / inline, legacy VTK binary / ASCII):

- ``flip``: a few random bytes changed, in the header or in the payload;
- ``cut``: the file truncated at a random point;
- ``lie``: a header field that declares more or less data than there is;
- ``special``: the values that broke readers before (dims 32767^3, negative, 2^40, datatype 999, vox_offset 0,
  DimSize 1e5^3, CompressedDataSize 1e12, WholeExtent 1e5^3, data file = FIFO or /dev/zero, line skip 1e9...).

Each variant says whether it *must* be refused (its payload is damaged or its header is invalid) or may load
(a flipped byte in free text or in uncompressed voxels cannot be detected). A DICOM folder with one damaged file
may load if a warning names that file.

:func:`run_variants` loads the variants in a worker process (in-process ``load_volume`` calls, one process for many
files) under an address-space limit and a per-file timeout; a crash or hang kills only the worker, which is
restarted after the variant that caused it. :func:`run_cli` runs ``voxelscope info`` on some of them.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from .fuzz_bases import Base, make_bases
from .fuzz_edits import special_variants

SEED = 20
ROOT = Path(__file__).resolve().parents[3]


@dataclass
class Variant:
    """One damaged file: where it is, what was done, and what the reader must do."""

    name: str
    fmt: str
    kind: str  # flip, cut, lie, special
    path: Path  # what load_volume is given (a file or a DICOM folder)
    must_fail: bool
    damaged_file: str = ""  # DICOM: the file whose damage may instead be reported as a warning
    names: tuple[str, ...] = ()  # file names an error may name (the file and its companions)
    base_path: Path | None = None  # the intact file the variant was made from


@dataclass
class Outcome:
    variant: Variant
    status: str  # loaded, refused, traceback, crash, hang, memory
    message: str = ""
    warnings: list[str] = field(default_factory=list)
    unexpected: bool = False
    seconds: float = 0.0
    rss_growth_mb: float = 0.0
    digest: str = ""  # of the loaded volume (values, geometry, modality)
    base_digest: str = ""  # of the intact base file's volume

    @property
    def problems(self) -> list[str]:
        """Ways this outcome breaks the contract (empty when it keeps it)."""
        v, found = self.variant, []
        if self.status in ("traceback", "crash", "hang", "memory"):
            found.append(self.status)
        if self.status == "refused":
            if "\n" in self.message:
                found.append("multi-line message")
            if not any(n in self.message for n in v.names):
                found.append("message names no file")
        if self.status == "loaded" and v.must_fail:
            warned = v.damaged_file and any(v.damaged_file in w for w in self.warnings)
            # A damaged byte that changes nothing (an unused field, padding) is not damaged data.
            unchanged = self.digest and self.digest == self.base_digest
            if not (warned or unchanged):
                found.append("damaged data accepted silently")
        if self.rss_growth_mb > 1500:
            found.append("memory runaway")
        return found


def generate(folder: Path, *, seed: int = SEED, flips: int = 12, cuts: int = 8) -> list[Variant]:
    """All variants, written under ``folder`` (deterministic for a seed)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    bases = make_bases(folder / "bases")
    variants: list[Variant] = []
    for base in bases:
        for i in range(flips):
            variants.append(_flip(base, folder, rng, i))
        for i in range(cuts):
            variants.append(_cut(base, folder, rng, i))
        for name, edit, must_fail in special_variants(base):
            target = base.copy_to(folder / f"{base.name}-{name}")
            edit(target)
            kind = "lie" if name.startswith("lie") else "special"
            variants.append(_variant(base, target, f"{base.name}/{name}", kind, must_fail))
    return variants


def _variant(base: Base, target: Base, name: str, kind: str, must_fail: bool) -> Variant:
    names = tuple({p.name for p in target.files} | {target.load_path.name})
    return Variant(name, base.fmt, kind, target.load_path, must_fail,
                   damaged_file=target.damaged.name if base.fmt == "DICOM" else "", names=names,
                   base_path=base.load_path)


def _flip(base: Base, folder: Path, rng, index: int) -> Variant:
    target = base.copy_to(folder / f"{base.name}-flip{index:02d}")
    file = target.damaged
    data = bytearray(file.read_bytes())
    in_header = index % 2 == 0 or target.payload_start(file) >= len(data)
    payload = target.payload_start(file)
    if not in_header and data[payload:payload + 2] == b"\x1f\x8b":
        payload += 10  # a gzip member header (time stamp, flags, OS) is not covered by its CRC
    start, stop = (0, target.payload_start(file)) if in_header else (payload, len(data))
    positions = rng.integers(start, max(stop, start + 1), size=int(rng.integers(1, 4)))
    for position in positions:
        if position < len(data):
            data[position] ^= int(rng.integers(1, 256))
    file.write_bytes(bytes(data))
    must_fail = (not in_header) and target.payload_checked(file)
    return _variant(base, target, f"{base.name}/flip{index:02d}-{'header' if in_header else 'payload'}", "flip",
                    must_fail)


def _cut(base: Base, folder: Path, rng, index: int) -> Variant:
    target = base.copy_to(folder / f"{base.name}-cut{index:02d}")
    file = target.damaged
    data = file.read_bytes()
    at = int(rng.integers(0, max(len(data) - 1, 1)))
    file.write_bytes(data[:at])
    # A cut removes part of the payload (or the whole header of an attached file): the file is damaged.
    must_fail = at < target.payload_end(file)
    return _variant(base, target, f"{base.name}/cut{index:02d}-at{at}", "cut", must_fail)


# ----------------------------------------------------------------------------------------------------------------
# Running
# ----------------------------------------------------------------------------------------------------------------
def worker_main() -> None:  # pragma: no cover - runs in the worker process
    """Read variant paths (JSON lines) on stdin; load each; report one JSON line per step on stdout."""
    import resource
    import traceback
    import warnings

    warnings.simplefilter("ignore")
    from app.io import VolumeReadError, load_volume
    from app.vtk_setup import configure_vtk

    configure_vtk()
    limit = int(os.environ.get("FUZZ_ADDRESS_SPACE", "0"))
    if limit:
        with open("/proc/self/status") as handle:
            used = next(int(line.split()[1]) * 1024 for line in handle if line.startswith("VmSize:"))
        resource.setrlimit(resource.RLIMIT_AS, (used + limit, used + limit))
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        job = json.loads(line)
        print(json.dumps({"start": job["index"]}), flush=True)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        started = time.monotonic()
        result = {"index": job["index"]}
        try:
            volume = load_volume(job["path"])
            result.update(status="loaded", warnings=list(volume.metadata.get("warnings", [])), digest=_digest(volume))
            del volume
        except VolumeReadError as exc:
            cause = exc.__cause__
            status = "memory" if isinstance(cause, MemoryError) else "refused"
            result.update(status=status, message=str(exc), unexpected=bool(getattr(exc, "unexpected", False)))
        except MemoryError as exc:
            result.update(status="memory", message=f"MemoryError: {exc}")
        except BaseException as exc:  # the contract is broken: record it
            result.update(status="traceback", message="".join(traceback.format_exception_only(type(exc), exc)))
        result["seconds"] = time.monotonic() - started
        result["rss_growth_mb"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
        print(json.dumps(result), flush=True)


def _digest(volume) -> str:
    import hashlib

    import numpy as np

    digest = hashlib.sha1(np.ascontiguousarray(volume.array).tobytes())
    digest.update(str(volume.array.dtype).encode())
    geometry = np.round(np.concatenate([volume.spacing, volume.origin, np.ravel(volume.direction)]), 4) + 0.0
    digest.update(geometry.tobytes() + f"{volume.modality}/{volume.units}".encode())
    return digest.hexdigest()


def _start_worker(address_space: int):
    env = dict(os.environ, FUZZ_ADDRESS_SPACE=str(address_space), PYTHONWARNINGS="ignore")
    process = subprocess.Popen(
        [sys.executable, "-c", "from tests.app.io.fuzz import worker_main; worker_main()"],
        cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env,
        bufsize=1,
    )
    process.lines = queue.Queue()

    def pump():  # a thread owns the pipe: lines arriving together are never lost in a buffer
        for line in process.stdout:
            process.lines.put(line)
        process.lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    _read_line(process, 120)
    return process


def _read_line(process, timeout: float) -> dict | None:
    try:
        line = process.lines.get(timeout=timeout)
    except queue.Empty:
        return None
    return json.loads(line) if line else None


def run_variants(variants: list[Variant], *, timeout: float = 30.0, address_space: int = 2 << 30) -> list[Outcome]:
    """Load every variant in worker processes (see the module notes); one :class:`Outcome` each.

    The intact base files are loaded first, so a damaged file that loads can be compared with its original.
    """
    bases = sorted({v.base_path for v in variants if v.base_path is not None})
    probes = [Variant(f"base:{p}", "base", "base", p, False, names=(p.name,)) for p in bases]
    results = _run(probes + list(variants), timeout, address_space)
    reference = {probe.path: outcome.digest for probe, outcome in zip(probes, results)}
    outcomes = results[len(probes):]
    for outcome in outcomes:
        outcome.base_digest = reference.get(outcome.variant.base_path, "")
    return outcomes


def _run(variants: list[Variant], timeout: float, address_space: int) -> list[Outcome]:
    outcomes: list[Outcome] = []
    process = None
    for index, variant in enumerate(variants):
        if process is None or process.poll() is not None:
            process = _start_worker(address_space)
        process.stdin.write(json.dumps({"index": index, "path": str(variant.path)}) + "\n")
        process.stdin.flush()
        started = _read_line(process, timeout)
        result = _read_line(process, timeout) if started else None
        if result is None:
            if process.poll() is None:
                process.kill()
                process.wait()
                outcomes.append(Outcome(variant, "hang", f"no answer in {timeout} s"))
            else:
                code = process.returncode
                outcomes.append(Outcome(variant, "crash", f"worker exit {code} ({_signal_name(code)})"))
            process = None
            continue
        outcomes.append(Outcome(variant, result["status"], result.get("message", ""), result.get("warnings", []),
                                result.get("unexpected", False), result["seconds"], result["rss_growth_mb"],
                                result.get("digest", "")))
    if process is not None:
        process.stdin.close()
        process.wait(timeout=30)
    return outcomes


def _signal_name(code: int) -> str:
    if code is not None and code < 0:
        return signal.Signals(-code).name
    return {134: "abort", 139: "segfault"}.get(code, "exit")


def run_cli(variants: list[Variant], *, timeout: float = 60.0, address_space: int = 3 << 30) -> list[Outcome]:
    """``voxelscope info PATH`` on each variant: exit 0, or 1 with one ``voxelscope: error:`` line naming the file."""
    executable = Path(sys.executable).parent / "voxelscope"
    outcomes = []

    def limit():  # pragma: no cover - runs in the child
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (address_space + (3 << 30), address_space + (3 << 30)))

    for variant in variants:
        started = time.monotonic()
        try:
            done = subprocess.run([str(executable), "info", str(variant.path)], capture_output=True, text=True,
                                  timeout=timeout, preexec_fn=limit, cwd=ROOT)
        except subprocess.TimeoutExpired:
            outcomes.append(Outcome(variant, "hang", f"no exit in {timeout} s"))
            continue
        seconds = time.monotonic() - started
        stderr = done.stderr.strip()
        if done.returncode == 0:
            outcomes.append(Outcome(variant, "loaded", warnings=[done.stdout], seconds=seconds))
        elif done.returncode == 1 and stderr.startswith("voxelscope: error:") and "Traceback" not in stderr:
            outcomes.append(Outcome(variant, "refused", stderr, seconds=seconds))
        elif done.returncode < 0 or done.returncode in (134, 139):
            outcomes.append(Outcome(variant, "crash", f"exit {done.returncode}: {stderr[-300:]}", seconds=seconds))
        else:
            outcomes.append(Outcome(variant, "traceback", f"exit {done.returncode}: {stderr[-600:]}", seconds=seconds))
    return outcomes


def summary(outcomes: list[Outcome]) -> dict:
    """Counts per format and status, and the broken ones."""
    table: dict = {}
    for outcome in outcomes:
        row = table.setdefault(outcome.variant.fmt, {})
        row[outcome.status] = row.get(outcome.status, 0) + 1
        row["variants"] = row.get("variants", 0) + 1
        if outcome.unexpected:
            row["net"] = row.get("net", 0) + 1
    broken = [(o.variant.name, o.problems, o.message[:300]) for o in outcomes if o.problems]
    return {"per_format": table, "broken": broken, "total": len(outcomes)}
