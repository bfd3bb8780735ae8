"""Every import inside a function of ``app/`` has a reason, and none of them dodges an import cycle.

An import belongs at the top of its module unless putting it there costs something real. The reasons accepted here,
computed from the sources (no module is imported):

- the command line: modules of ``app/cli`` load what a subcommand needs when that subcommand runs, so that
  ``voxelscope --help`` and every other subcommand start without it;
- a heavy dependency the importing module does not load otherwise: one of :data:`HEAVY` (for VTK, the module
  itself: each ``vtkmodules.vtk*`` is a shared library of its own), or a module of ours whose module-level imports
  bring one in;
- an optional dependency (:data:`OPTIONAL`): a reference implementation the benchmarks compare against, or a module
  that exists on some platforms only;
- a function shipped as source text to another process (:data:`STANDALONE`), which has only its own imports.

An import whose target, at module level, imports the importing module back (directly or through other modules) is
a cycle and never accepted. Run ``pytest tests/test_function_imports.py -s`` to see the list with its reasons.
"""

from __future__ import annotations

import ast
import collections
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("app", "algorithms")

#: Packages whose import takes long or loads large native libraries (checked by top-level name; VTK by module).
HEAVY = frozenset({"vtkmodules", "vtk", "pyvista", "matplotlib", "dask", "distributed", "zarr", "numcodecs", "scipy",
                   "pydicom", "pynetdicom", "nibabel", "nrrd", "meshio", "numba", "h5py"})
#: Modules whose functions run elsewhere as source text, so each must import what it uses itself.
STANDALONE = {"app.bench.compile": "runs as source in a fresh process (worker_program): imports its own"}
#: Packages that may be missing: the benchmarks' references (the ``bench`` extra), psutil (installed with dask's
#: distributed scheduler, not a dependency of ours), ``resource`` (POSIX only).
OPTIONAL = frozenset({"manifold3d", "tetgen", "pytetwild", "psutil", "resource"})


@dataclass(frozen=True)
class FunctionImport:
    module: str
    line: int
    target: str
    reason: str  # empty: none


def _modules() -> dict[str, tuple[Path, bool]]:
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            is_package = parts[-1] == "__init__"
            found[".".join(parts[:-1] if is_package else parts)] = (path, is_package)
    return found


def _targets(module: str, is_package: bool, node, modules) -> list[str]:
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module
    submodules = [f"{target}.{alias.name}" for alias in node.names if f"{target}.{alias.name}" in modules]
    return [target, *submodules]


def _scan():
    """Module-level imports of every module (outside ``if TYPE_CHECKING``), and every import inside a function."""
    modules = _modules()
    top = collections.defaultdict(set)
    inside = []

    def visit(module, is_package, node, in_function, type_checking):
        for child in ast.iter_child_nodes(node):
            function = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            checking = type_checking or (isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test))
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                for target in _targets(module, is_package, child, modules):
                    if in_function:
                        inside.append((module, child.lineno, target))
                    elif not checking:
                        top[module].add(target)
            visit(module, is_package, child, function, checking)

    for module, (path, is_package) in modules.items():
        visit(module, is_package, ast.parse(path.read_text(encoding="utf-8")), False, False)
    return top, inside


def function_imports() -> list[FunctionImport]:
    """Every import inside a function of ``app/``, with its reason (empty where it has none)."""
    top, inside = _scan()

    def loaded(module: str, skip: frozenset = frozenset()) -> set[str]:
        """What importing ``module`` loads at module level, transitively (its packages' ``__init__`` included,
        except those in ``skip``: the importer's own packages, already loading when it runs)."""
        seen: set[str] = set()
        stack = [module]
        while stack:
            name = stack.pop()
            parts = name.split(".")
            for i in range(1, len(parts) + 1):
                prefix = ".".join(parts[:i])
                if prefix not in seen and prefix not in skip:
                    seen.add(prefix)
                    stack.extend(top.get(prefix, ()))
        return seen

    def heavy(names: set[str]) -> set[str]:
        return {name if name.startswith("vtkmodules.") else name.split(".")[0] for name in names
                if name.split(".")[0] in HEAVY and name != "vtkmodules"}

    found = []
    for module, line, target in inside:
        if not module.startswith("app"):
            continue
        parts = module.split(".")
        own_packages = frozenset(".".join(parts[:i]) for i in range(1, len(parts)))
        if target.startswith(module + "."):  # a package importing its own submodule: the package is loading
            own_packages |= {module}
        top_name = target.split(".")[0]
        reason = ""
        if top_name in PACKAGES and module in loaded(target, own_packages):
            reason = ""  # a cycle: never a reason, whatever else holds
        elif module in STANDALONE:
            reason = STANDALONE[module]
        elif module.startswith("app.cli"):
            reason = "command line: loaded when the subcommand runs"
        elif top_name in OPTIONAL:
            reason = f"optional dependency: {top_name}"
        elif top_name in PACKAGES:
            extra = heavy(loaded(target, own_packages)) - heavy(loaded(module))
            if extra:
                reason = f"pulls in {', '.join(sorted(extra)[:3])}{' ...' if len(extra) > 3 else ''}"
        else:
            extra = heavy({target}) - heavy(loaded(module))
            if extra:
                reason = f"heavy dependency: {', '.join(sorted(extra))}"
        found.append(FunctionImport(module, line, target, reason))
    return found


def test_every_function_level_import_in_app_names_its_reason():
    imports = function_imports()
    assert len(imports) > 100  # the scan finds them (the window's command line alone has dozens)
    by_reason = collections.Counter(i.reason.split(":")[0].split(" ")[0] for i in imports)
    print(f"\n{len(imports)} imports inside functions of app/: {dict(by_reason)}")
    for item in imports:
        print(f"  {item.module}:{item.line} {item.target} - {item.reason or 'NO REASON'}")
    missing = [f"{i.module}:{i.line} imports {i.target}" for i in imports if not i.reason]
    assert not missing, ("imports inside functions with no reason (move them to the top of the module; if that makes "
                         "a cycle, move the shared code instead):\n" + "\n".join(missing))


def test_the_scan_sees_a_cycle_and_a_reasonless_import(tmp_path, monkeypatch):
    """The rules on a small package: a cycle dodged inside a function and a light import are refused, a heavy one
    is accepted."""
    package = tmp_path / "app"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from app import b\n\ndef f():\n    from app import c\n    import json\n")
    (package / "b.py").write_text("def g():\n    from app import a\n    import zarr\n")
    (package / "c.py").write_text("import numpy\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    reasons = {(i.module, i.target): i.reason for i in function_imports()}
    assert reasons[("app.b", "app.a")] == ""  # app.a imports app.b at module level: a cycle
    assert reasons[("app.a", "app.c")] == ""  # nothing heavy: belongs at the top
    assert reasons[("app.a", "json")] == ""
    assert reasons[("app.b", "zarr")] == "heavy dependency: zarr"
