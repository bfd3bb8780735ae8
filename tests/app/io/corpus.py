"""The real files that ship in the pydicom, pydicom-data and nibabel wheels, prepared for the readers.

Each file is copied into a folder of its own (a DICOM slice would otherwise pull in the series of every other test
file in pydicom's folder); gzipped DICOM and NIfTI files are also offered decompressed.
"""

from __future__ import annotations

import gzip
import importlib.util
import shutil
from pathlib import Path

from .fuzz import Variant


def corpus_roots() -> dict[str, Path]:
    """Where each wheel keeps its test files (only the wheels that are installed)."""
    roots = {}
    for name, module, parts in (("pydicom", "pydicom", ("data",)),
                                ("pydicom-data", "data_store", ("data",)),
                                ("nibabel", "nibabel", ())):
        spec = importlib.util.find_spec(module)
        if spec is None or spec.origin is None:
            continue
        roots[name] = Path(spec.origin).parent.joinpath(*parts)
    return roots


def corpus_files(root: Path, wheel: str) -> list[Path]:
    if wheel == "nibabel":
        files = [p for folder in root.rglob("data") if folder.is_dir() and "tests" in folder.parts
                 for p in folder.rglob("*")]
    else:
        files = list(root.rglob("*"))
    return sorted(p for p in files if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts)


def prepare(folder: Path) -> list[Variant]:
    """One variant per corpus file (each alone in a folder), plus the decompressed twin of each .gz file."""
    variants = []
    for wheel, root in corpus_roots().items():
        for index, source in enumerate(corpus_files(root, wheel)):
            home = folder / wheel / f"{index:04d}"
            home.mkdir(parents=True)
            copy = home / source.name
            shutil.copyfile(source, copy)
            relative = source.relative_to(root)
            variants.append(Variant(f"{wheel}/{relative}", wheel, "real", copy, False, names=(source.name,)))
            if source.name.endswith(".gz") and not source.name.endswith((".nii.gz", ".mnc.gz", ".nrrd.gz")):
                inner = home / "inflated" / source.name[:-3]
                inner.parent.mkdir()
                try:
                    inner.write_bytes(gzip.decompress(source.read_bytes()))
                except (OSError, EOFError):
                    shutil.rmtree(inner.parent)
                    continue
                variants.append(Variant(f"{wheel}/{relative} (inflated)", wheel, "real", inner, False,
                                        names=(inner.name,)))
    return variants


__all__ = ["corpus_files", "corpus_roots", "prepare"]
