"""Voxelscope's bundled sample volumes, installed with the package (see README.md in this folder).

Only data lives here; :mod:`app.samples` names the samples and finds them with :func:`files`.
"""

from importlib import resources
from pathlib import Path


def files() -> Path:
    """The folder holding the sample files (inside the installed package or the source checkout)."""
    return Path(str(resources.files(__name__)))
