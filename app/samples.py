"""The bundled sample volumes and the names that reach them from the command line and the workbench.

``voxelscope gui sample`` (or ``info sample``, ``render sample`` ...) opens the CT sample, the FORBILD head phantom
on a CT table (:func:`app.datasets.ct_head_phantom`), shipped as NIfTI in the ``sample_volumes`` package;
``sample:dicom`` is the same scan as a DICOM series (one file per slice, written on first use into the per-user
cache, :func:`app.user_dirs.cache_dir`), so the DICOM reader runs on it; ``sample:mri`` opens the Colin 27 brain
MRI, which is not copied into the project but read where Debian's ``mricron-data`` package installs it (the set-up
scripts install that package).

``python -m app.samples`` regenerates the CT sample file from :func:`app.datasets.ct_head_phantom`, bit for bit.
"""

from __future__ import annotations

import hashlib
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from sample_volumes import files as _sample_files

from .user_dirs import cache_dir

#: Colin 27 as Debian's ``mricron-data`` installs it (``apt-get install mricron-data``).
MRICRON_COLIN27 = Path("/usr/share/mricron/templates/ch2.nii.gz")
#: The CT sample's file inside the ``sample_volumes`` package.
CT_FILE = "ct_forbild_head.nii.gz"


@dataclass(frozen=True)
class Sample:
    name: str
    description: str


#: name -> what it is (as ``voxelscope info`` and the File menu say it)
SAMPLES = {
    "ct": Sample("ct", "FORBILD head phantom (Lauritsch and Bruder) with scalp, head rest and CT table, 512 x 512 x "
                       "176 voxels, 0.547 x 0.547 x 1.5 mm, int16 HU, made by Voxelscope"),
    "dicom": Sample("dicom", "the CT sample as a DICOM series: 176 CT image files of 512 x 512 pixels, "
                             "RescaleIntercept -1024 HU, written once into the user's cache"),
    "mri": Sample("mri", "Colin 27 T1 brain MRI, 181 x 217 x 181 voxels, 1 mm, uint8 (Debian package mricron-data)"),
}
DEFAULT_SAMPLE = "ct"


def sample_path(name: str = DEFAULT_SAMPLE) -> Path:
    """Path of a sample by short name (``ct``, ``dicom`` or ``mri``); a one-line ``ValueError`` when it cannot be had."""
    if name not in SAMPLES:
        raise ValueError(f"unknown sample {name!r}; choose one of {', '.join(SAMPLES)}")
    if name == "ct":
        return _sample_files() / CT_FILE
    if name == "dicom":
        return dicom_sample_folder()
    if not MRICRON_COLIN27.exists():
        raise ValueError(f"the MRI sample ({MRICRON_COLIN27}) is not installed: it comes with Debian's mricron-data "
                         "package; run 'sudo apt-get install mricron-data' (scripts/voxelscope does it for you)")
    return MRICRON_COLIN27


def sample_name(text: str) -> str | None:
    """The sample's short name when ``text`` names one (``sample`` or ``sample:NAME``), else None."""
    if text == "sample":
        return DEFAULT_SAMPLE
    if text.startswith("sample:"):
        return text.split(":", 1)[1]
    return None


def resolve_path(text: str) -> Path:
    """Turn ``sample`` / ``sample:NAME`` into the sample's path; anything else is a path as given."""
    name = sample_name(text)
    return sample_path(name) if name is not None else Path(text).expanduser()


def load_sample(name: str = DEFAULT_SAMPLE):
    """The sample as a :class:`~app.volume.Volume`, read from its file as a user's would be."""
    from .io import load_volume

    return load_volume(sample_path(name))


def dicom_sample_folder() -> Path:
    """The CT sample as a DICOM series in the user's cache, written on first use (deterministic UIDs).

    The folder's name carries a hash of the NIfTI it was made from, so a changed sample makes a new series; it is
    written into a temporary folder and renamed into place, so two processes asking at once never see half a series.
    """
    source = sample_path("ct")
    digest = hashlib.sha256(source.read_bytes()).hexdigest()[:16]
    folder = cache_dir() / "samples" / f"ct-dicom-{digest}"
    if folder.is_dir():
        return folder
    from .io import load_volume, write_dicom_series

    folder.parent.mkdir(parents=True, exist_ok=True)
    volume = load_volume(source)
    with tempfile.TemporaryDirectory(dir=folder.parent, prefix=".writing-") as temporary:
        staging = Path(temporary) / "series"
        write_dicom_series(volume, staging, rescale_intercept=-1024, description="FORBILD HEAD 1.5 mm",
                           uid_seed=f"voxelscope-forbild-{digest}", patient_name="FORBILD^Head phantom",
                           patient_id="FORBILD-HEAD")
        try:
            staging.rename(folder)
        except OSError:
            if not folder.is_dir():  # another process won the race when the folder exists now
                raise
            shutil.rmtree(staging, ignore_errors=True)
    return folder


def regenerate_ct_sample(path: Path | None = None) -> Path:
    """Write the CT sample NIfTI (deterministic); overwrites the bundled file."""
    from .datasets import ct_head_phantom
    from .io import save_volume

    path = path or sample_path("ct")
    return save_volume(ct_head_phantom(), path, overwrite=True)


if __name__ == "__main__":  # pragma: no cover - maintenance entry point
    print(regenerate_ct_sample(Path(sys.argv[1]) if len(sys.argv) > 1 else None))
