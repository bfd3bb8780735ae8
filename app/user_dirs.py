"""The per-user folder where Voxelscope keeps what it can make again: generated samples and the like.

``$VOXELSCOPE_CACHE_DIR`` when set, else ``$XDG_CACHE_HOME/voxelscope`` (``~/.cache/voxelscope``). Compiled kernels
have their own folder beside it (:func:`algorithms.common.kernel_cache.cache_root`). Nothing the user made is kept
here: deleting the folder costs only the time to make its contents again.
"""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path:
    """The per-user cache folder (not created)."""
    chosen = os.environ.get("VOXELSCOPE_CACHE_DIR")
    if chosen:
        return Path(chosen).expanduser()
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "voxelscope"
