"""Where compiled kernels are kept: one per-user folder that a fresh checkout of the same sources finds filled, keyed
by a kernel's module and everything of the package it imports, so editing a shared helper recompiles its users."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from algorithms.common import kernel_cache

ROOT = Path(kernel_cache.PACKAGE_ROOT)

#: Calls a small kernel of ``algorithms.common.pixel_rays`` and prints how many of the package's kernels numba
#: compiled in this process (0 when it came from the cache).
_PROBE = """
import json, numpy as np
from numba.core import event
compiled = []
class Listener(event.Listener):
    def on_start(self, ev):
        name = getattr(getattr(ev.data.get("dispatcher"), "py_func", None), "__module__", "") or ""
        if name.startswith("algorithms."):
            compiled.append(name)
    def on_end(self, ev):
        pass
event.register("numba:compile", Listener())
import algorithms
from algorithms.common.pixel_rays import pixel_ray
frame = np.array([[0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], [0, 0, 0]], dtype=np.float64)
pixel_ray(frame, True, 2, 3)
print(json.dumps({"compiled": compiled, "package": algorithms.__file__}))
"""


def _checkout(tmp_path: Path, name: str) -> Path:
    """A copy of the package as another clone would hold it (a different folder, files written anew)."""
    target = tmp_path / name
    shutil.copytree(ROOT, target / ROOT.name, ignore=shutil.ignore_patterns("__pycache__"))
    return target


def _run(checkout: Path, cache: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(checkout), VOXELSCOPE_NUMBA_CACHE=str(cache))
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)  # set by this process's own import of algorithms
    done = subprocess.run([sys.executable, "-c", _PROBE], cwd=checkout, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(report["package"]).parent.parent == checkout  # the copy ran, not the project
    return report


def test_install_puts_our_locator_first_and_keeps_numbas(monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_LOCATOR_CLASSES", raising=False)
    kernel_cache.install()
    kernel_cache.install()  # idempotent
    classes = os.environ["NUMBA_CACHE_LOCATOR_CLASSES"].split(",")
    assert classes[0] == kernel_cache.LOCATOR_PATH and classes.count(kernel_cache.LOCATOR_PATH) == 1
    assert set(kernel_cache.NUMBA_LOCATORS) <= set(classes)


def test_cache_root_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("VOXELSCOPE_NUMBA_CACHE", str(tmp_path / "kernels"))
    assert kernel_cache.cache_root() == tmp_path / "kernels"
    monkeypatch.delenv("VOXELSCOPE_NUMBA_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert kernel_cache.cache_root() == tmp_path / "xdg" / "voxelscope" / "numba"


def test_a_kernel_depends_on_the_modules_it_imports_and_nothing_else():
    closure = kernel_cache.dependencies(str(ROOT / "rendering" / "raymarch" / "kernels.py"))
    names = {str(path.relative_to(ROOT)) for path in closure}
    assert {"rendering/raymarch/kernels.py", "common/sampling.py", "common/pixel_rays.py", "__init__.py",
            "rendering/__init__.py"} <= names
    assert not any(name.startswith(("fields/", "surfaces/", "meshing/")) for name in names)


def test_a_fresh_checkout_finds_its_kernels_compiled_and_an_edited_import_recompiles(tmp_path):
    cache = tmp_path / "cache"
    first = _run(_checkout(tmp_path, "clone-a"), cache)
    assert first["compiled"] == ["algorithms.common.pixel_rays"]
    assert list(cache.rglob("*.nbi")) and list(cache.rglob("*.nbc"))
    # Another clone of the same sources, elsewhere, with new file times: nothing to compile.
    assert _run(_checkout(tmp_path, "clone-b"), cache)["compiled"] == []
    # A clone where a module the kernel's module imports changed (the package's __init__ here): compiled again.
    edited = _checkout(tmp_path, "clone-c")
    with open(edited / ROOT.name / "common" / "__init__.py", "a") as handle:
        handle.write("\n# an edit\n")
    assert _run(edited, cache)["compiled"] == ["algorithms.common.pixel_rays"]


@pytest.mark.parametrize("name", ["rendering/raymarch/kernels.py", "surfaces/marching_cubes/kernels.py"])
def test_source_stamp_is_stable_and_depends_on_the_module(name):
    path = str(ROOT / name)
    assert kernel_cache.source_stamp(path) == kernel_cache.source_stamp(path)
    other = str(ROOT / "fields" / "distance" / "propagate.py")
    assert kernel_cache.source_stamp(path) != kernel_cache.source_stamp(other)
