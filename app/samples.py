"""The bundled sample volumes and the names that reach them from the command line and the workbench.

``voxelscope gui sample`` (or ``info sample``, ``render sample`` ...) opens the CT head phantom; ``sample:mri``
opens the Colin 27 brain MRI. The files live in the repository's ``sample_volumes/`` folder (see its README).
``python -m app.samples`` regenerates the phantom file from :func:`app.datasets.ct_head_phantom`, bit for bit.
"""

from __future__ import annotations

import sys
from pathlib import Path

SAMPLE_FOLDER = Path(__file__).resolve().parent.parent / "sample_volumes"

#: name -> (file name, description)
SAMPLES = {
    "ct": ("ct_head_phantom.nii.gz", "synthetic CT head phantom, 256x256x108, 0.94 x 0.94 x 2.0 mm, int16 HU"),
    "mri": ("colin27_t1_ch2.nii.gz", "Colin 27 T1 brain MRI, 181x217x181, 1 mm, uint8"),
}
DEFAULT_SAMPLE = "ct"


def sample_path(name: str = DEFAULT_SAMPLE) -> Path:
    """Path of a bundled sample by short name (``ct`` or ``mri``)."""
    if name not in SAMPLES:
        raise ValueError(f"unknown sample {name!r}; choose one of {', '.join(SAMPLES)}")
    return SAMPLE_FOLDER / SAMPLES[name][0]


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
