"""The bundled sample volumes and the names that reach them from the command line and the workbench.

``voxelscope gui sample`` (or ``info sample``, ``render sample`` ...) opens the CT head phantom; ``sample:mri``
opens the Colin 27 brain MRI. The phantom lives in the repository's ``sample_volumes/`` folder (see its README); the
MRI is not copied into the repository but read where Debian's ``mricron-data`` package installs it (the set-up
scripts install that package).
``python -m app.samples`` regenerates the phantom file from :func:`app.datasets.ct_head_phantom`, bit for bit.
"""

from __future__ import annotations

import sys
from pathlib import Path

SAMPLE_FOLDER = Path(__file__).resolve().parent.parent / "sample_volumes"

#: Colin 27 as Debian's ``mricron-data`` installs it (``apt-get install mricron-data``).
MRICRON_COLIN27 = Path("/usr/share/mricron/templates/ch2.nii.gz")

#: name -> (file, description)
SAMPLES = {
    "ct": (SAMPLE_FOLDER / "ct_head_phantom.nii.gz",
           "synthetic CT head phantom, 256x256x108, 0.94 x 0.94 x 2.0 mm, int16 HU"),
    "mri": (MRICRON_COLIN27, "Colin 27 T1 brain MRI, 181x217x181, 1 mm, uint8 (Debian package mricron-data)"),
}
DEFAULT_SAMPLE = "ct"


def sample_path(name: str = DEFAULT_SAMPLE) -> Path:
    """Path of a sample by short name (``ct`` or ``mri``); a one-line ``ValueError`` when it is not installed."""
    if name not in SAMPLES:
        raise ValueError(f"unknown sample {name!r}; choose one of {', '.join(SAMPLES)}")
    path = SAMPLES[name][0]
    if name == "mri" and not path.exists():
        raise ValueError(f"the MRI sample ({path}) is not installed: it comes with Debian's mricron-data package; "
                         "run 'sudo apt-get install mricron-data' (scripts/voxelscope does it for you)")
    return path


def resolve_path(text: str) -> Path:
    """Turn ``sample`` / ``sample:NAME`` into the bundled file's path; anything else is a path as given."""
    if text == "sample":
        return sample_path(DEFAULT_SAMPLE)
    if text.startswith("sample:"):
        return sample_path(text.split(":", 1)[1])
    return Path(text).expanduser()


def regenerate_phantom(path: Path | None = None) -> Path:
    """Write the CT head phantom NIfTI (deterministic); overwrites the bundled file."""
    from .datasets import ct_head_phantom
    from .io import save_volume

    path = path or sample_path("ct")
    return save_volume(ct_head_phantom(), path, overwrite=True)


if __name__ == "__main__":  # pragma: no cover - maintenance entry point
    print(regenerate_phantom(Path(sys.argv[1]) if len(sys.argv) > 1 else None))
