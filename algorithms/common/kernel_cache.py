"""Where numba keeps the compiled kernels: one per-user folder, shared by every checkout of the same sources.

numba compiles a kernel on its first call (15 to 40 s for the large ones) and, with ``cache=True``, stores the
machine code beside the source in ``__pycache__``. That cache dies with the checkout (a fresh clone, a wheel
installed into a new environment) and is stale when a kernel's callee in another module changes (numba's index is
keyed by the kernel's own file, bytecode and signature, not by the functions it calls or the module constants it
freezes).

:class:`KernelCacheLocator` moves the cache of every kernel under ``algorithms/`` into a per-user folder
(:func:`cache_root`, ``~/.cache/voxelscope/numba`` by default, ``VOXELSCOPE_NUMBA_CACHE`` to choose another) keyed
by the kernel's path inside the package, not by where the checkout lies, so a fresh clone of the same sources finds
its kernels compiled. Its source stamp is a hash of the kernel's module *and every module of the package it imports,
transitively*: editing a shared inline helper recompiles the kernels that use it, and nothing else. numba adds the
signature, the CPU and its own version to each entry's key, so a cache shared between checkouts is safe.

:func:`install` registers the locator through numba's ``NUMBA_CACHE_LOCATOR_CLASSES`` setting (ahead of numba's own
locators, which still serve every other package). ``algorithms/__init__.py`` calls it before any kernel module is
imported, without importing numba itself.
"""

from __future__ import annotations

import ast
import hashlib
import os
import sys
from functools import lru_cache
from pathlib import Path

#: The package whose kernels are cached here (``algorithms/``).
PACKAGE_ROOT = Path(__file__).resolve().parent.parent
PACKAGE_NAME = PACKAGE_ROOT.name

#: The locator's dotted path, as numba's setting names it.
LOCATOR_PATH = f"{__name__}.KernelCacheLocator"
#: numba's own locators, tried after ours (the default order of ``numba.core.caching._CacheImpl``).
NUMBA_LOCATORS = ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator", "IPythonCacheLocator",
                  "ZipCacheLocator")

def cache_root() -> Path:
    """The per-user folder of compiled kernels: ``$VOXELSCOPE_NUMBA_CACHE``, else the user's cache folder."""
    chosen = os.environ.get("VOXELSCOPE_NUMBA_CACHE")
    if chosen:
        return Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or (Path.home() / ".cache")
    return Path(base) / "voxelscope" / "numba"


def install() -> None:
    """Put :class:`KernelCacheLocator` first among numba's cache locators (numba need not be imported yet)."""
    classes = ",".join((LOCATOR_PATH, *NUMBA_LOCATORS))
    current = os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES", "")
    if LOCATOR_PATH not in current.split(","):
        os.environ["NUMBA_CACHE_LOCATOR_CLASSES"] = classes if not current else f"{LOCATOR_PATH},{current}"
    config = sys.modules.get("numba.core.config")
    if config is not None and LOCATOR_PATH not in str(getattr(config, "CACHE_LOCATOR_CLASSES", "")).split(","):
        config.CACHE_LOCATOR_CLASSES = os.environ["NUMBA_CACHE_LOCATOR_CLASSES"]


def _module_file(dotted: str) -> Path | None:
    """The file of a module of the package by its dotted name (``algorithms.common.sampling``), or None."""
    parts = dotted.split(".")
    if parts[0] != PACKAGE_NAME:
        return None
    base = PACKAGE_ROOT.joinpath(*parts[1:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _dotted(path: Path) -> str:
    relative = path.relative_to(PACKAGE_ROOT).with_suffix("")
    parts = [PACKAGE_NAME, *relative.parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[Path]:
    """The package's modules that ``path`` imports (absolute or relative imports, submodules named in the list)."""
    package = _dotted(path) if path.name == "__init__.py" else _dotted(path).rpartition(".")[0]
    found: set[Path] = set()
    for node in ast.walk(ast.parse(path.read_bytes(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                source = ".".join([*anchor, node.module] if node.module else anchor)
            else:
                source = node.module or ""
            targets = [source, *(f"{source}.{alias.name}" for alias in node.names if alias.name != "*")]
        else:
            continue
        for target in targets:
            file = _module_file(target)
            if file is not None:
                found.add(file)
    # A module's packages run their __init__ first; they belong to what it depends on.
    for parent in path.parents:
        if parent == PACKAGE_ROOT.parent:
            break
        if (parent / "__init__.py").is_file() and parent / "__init__.py" != path:
            found.add(parent / "__init__.py")
    return found


def dependencies(path: str) -> set[Path]:
    """The module at ``path`` and every module of the package it imports, transitively (its packages' ``__init__``
    files included)."""
    seen: set[Path] = set()
    todo = [Path(path).resolve()]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        todo.extend(_imports(current) - seen)
    return seen


@lru_cache(maxsize=None)
def source_stamp(path: str) -> str:
    """SHA-256 of the module at ``path`` and of everything it depends on (:func:`dependencies`), with their paths
    inside the package."""
    digest = hashlib.sha256()
    for file in sorted(dependencies(path)):
        digest.update(str(file.relative_to(PACKAGE_ROOT)).encode())
        digest.update(file.read_bytes())
    return digest.hexdigest()


def _make_locator():
    from numba.core.caching import _CacheLocator

    class KernelCacheLocator(_CacheLocator):
        """numba cache locator for the kernels of ``algorithms/``: see the module's docstring."""

        def __init__(self, py_func, py_file):
            self._py_file = str(Path(py_file).resolve())
            self._lineno = py_func.__code__.co_firstlineno
            relative = Path(self._py_file).relative_to(PACKAGE_ROOT)
            self._cache_path = str(cache_root().joinpath(*relative.parent.parts) if relative.parent.parts
                                   else cache_root())

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):
            return source_stamp(self._py_file)

        def get_disambiguator(self):
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            try:
                Path(py_file).resolve().relative_to(PACKAGE_ROOT)
            except ValueError:
                return None  # not one of ours: numba's own locators take it
            if not os.path.isfile(py_file):
                return None
            self = cls(py_func, py_file)
            try:
                self.ensure_cache_path()
            except OSError:
                return None  # not writable: fall back to numba's locators
            return self

    return KernelCacheLocator


def __getattr__(name: str):
    # numba imports the locator class by name when it first caches a kernel; it is built then, so importing this
    # module (from ``algorithms/__init__``) does not import numba.
    if name == "KernelCacheLocator":
        value = _make_locator()
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
