"""The import layering ui -> app -> algorithms, the algorithm families above compare above common, and no Qt below
ui, checked by import-linter's contracts."""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: The algorithm packages the families contract names (its optional layers aside).
FAMILIES = tuple(f"algorithms/{name}" for name in ("common", "compare", "surfaces", "rendering", "references",
                                                    "datasets"))


def lint(directory: Path) -> subprocess.CompletedProcess:
    lint_imports = Path(sys.executable).with_name("lint-imports")
    return subprocess.run([str(lint_imports), "--config", str(directory / "pyproject.toml"), "--no-cache"],
                          cwd=directory, capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(directory), "PATH": str(lint_imports.parent)})


def test_contract_names_every_algorithm_family():
    """Every subpackage of algorithms is a layer of the families contract (a new family must be placed there)."""
    import tomllib

    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    families = next(c for c in contracts if c["name"].startswith("algorithms families"))
    named = {name.strip(" ()") for layer in families["layers"] for name in layer.split("|")}
    packages = {f"algorithms.{path.parent.name}" for path in (ROOT / "algorithms").glob("*/__init__.py")}
    assert packages <= named, packages - named
    assert {f"algorithms.{path.split('/')[1]}" for path in FAMILIES} <= named


def _contracts() -> list[dict]:
    import tomllib

    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]


def test_contract_names_every_module_of_app():
    """Every module of app but the command line and the benchmarks is a source of the contract that keeps them on
    top (a new module must be placed there)."""
    on_top = next(c for c in _contracts() if c["name"].startswith("Only the command line"))
    modules = {f"app.{path.stem if path.suffix else path.name}" for path in (ROOT / "app").iterdir()
               if (path.suffix == ".py" and path.stem != "__init__") or (path / "__init__.py").exists()}
    assert modules - {"app.cli", "app.bench"} == set(on_top["source_modules"]) - {"ui"}


def test_contracts_hold_for_the_project():
    result = lint(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"{len(_contracts())} kept, 0 broken" in result.stdout


@pytest.mark.parametrize(
    "module, source, broken",
    [
        ("algorithms/bad.py", "import app.volume\n", "Layers"),
        ("app/bad.py", "import qtpy\n", "never import Qt"),
        ("app/bad.py", "from ui import window\n", "Layers"),
        ("algorithms/surfaces/bad.py", "import algorithms.rendering\n", "families"),
        ("algorithms/rendering/bad.py", "from algorithms.references import vtk_surfaces\n", "families"),
        ("algorithms/datasets/bad.py", "import algorithms.surfaces\n", "families"),
        ("algorithms/compare/bad.py", "import algorithms.surfaces\n", "families"),
        ("algorithms/common/bad.py", "from algorithms.compare import measures\n", "families"),
        ("app/pipeline/bad.py", "from app.bench import common\n", "Only the command line"),
        ("app/labels/bad.py", "import app.cli\n", "Only the command line"),
        ("ui/bad.py", "from app.cli import mesh\n", "Only the command line"),
        ("app/bench/bad.py", "import app.cli\n", "never import the command line"),
        ("app/pipeline/bad.py", "from app.modes import get_mode\n", "takes modes, it never imports them"),
        ("app/pipeline/bad.py", "import app.operations\n", "takes modes, it never imports them"),
    ],
)
def test_contracts_catch_violations(tmp_path, module, source, broken):
    """The same contracts, applied to a tiny copy of the layout with one forbidden import, must fail."""
    for package in FAMILIES + ("algorithms", "app", "ui"):
        (tmp_path / package).mkdir(parents=True, exist_ok=True)
        (tmp_path / package / "__init__.py").write_text("")
    named = {name for contract in _contracts() if contract["type"] == "forbidden"
             for name in contract["source_modules"] + contract["forbidden_modules"] if name.startswith("app.")}
    for name in named | {"app.cli.common", "app.cli.mesh", "app.bench.common", "app.modes"}:  # the modules contracts name
        folder = tmp_path.joinpath(*name.split("."))
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "__init__.py").write_text("")
    (tmp_path / "ui" / "launch.py").write_text("import app.cli.common\n")  # the one import the contract allows
    for family in FAMILIES:  # modules the bad imports name
        for name in ("vtk_surfaces", "measures"):
            (tmp_path / family / f"{name}.py").write_text("")
    (tmp_path / "ui" / "window.py").write_text("import app\n")
    (tmp_path / "qtpy").mkdir()
    (tmp_path / "qtpy" / "__init__.py").write_text("")
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    (tmp_path / module).write_text(textwrap.dedent(source))
    result = lint(tmp_path)
    assert result.returncode != 0
    assert "BROKEN" in result.stdout and broken in result.stdout


# -- the shape of the code ------------------------------------------------------------------------------------------
def _tracked_python(*folders: str) -> list[Path]:
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", *folders], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout.split()
    return [ROOT / name for name in listed if name.endswith(".py") and (ROOT / name).exists()]


def test_the_window_never_branches_on_what_a_mode_is():
    """ui/ hosts the shared pipeline; deciding by a mode's kind or name belongs to app/ (the registry)."""
    import re

    pattern = re.compile(r"kind ==|\.kind in|mode\.name ==|\.output ==|\.output in")
    offenders = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
                 for path in _tracked_python("ui")
                 for number, line in enumerate(path.read_text().splitlines(), 1) if pattern.search(line)]
    assert not offenders, "\n".join(offenders)


def test_the_window_makes_no_standard_items_in_python():
    """A QStandardItem made in Python and handed to a model crashed the window when the model was deleted with a
    closed window's widgets (PySide released its wrapper: a segmentation fault, native stacks in docs/testing.md);
    combo rows are made through ``ui/combo_rows.py`` instead."""
    offenders = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
                 for path in _tracked_python("ui")
                 for number, line in enumerate(path.read_text().splitlines(), 1) if "QStandardItem(" in line]
    assert not offenders, "\n".join(offenders)


def test_no_module_is_longer_than_a_reader_can_hold():
    long = [f"{path.relative_to(ROOT)} ({count} lines)" for path in _tracked_python("algorithms", "app", "ui")
            if "tables" not in path.name and (count := len(path.read_text().splitlines())) > 600]
    assert not long, long


def test_the_window_class_stays_small():
    """MainWindow composes the window from parts that own their concerns; it stays at most 400 lines."""
    import ast

    tree = ast.parse((ROOT / "ui" / "main_window.py").read_text())
    window = next(node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "MainWindow")
    assert window.end_lineno - window.lineno + 1 <= 400


def test_sources_are_cited_by_title_not_by_a_path_outside_the_repository():
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout.split()
    texts = [ROOT / name for name in listed if name.endswith((".py", ".md")) and not name.startswith("tests/")
             and (ROOT / name).exists()]
    offenders = [str(path.relative_to(ROOT)) for path in texts if "shared/seeds" in path.read_text()]
    assert not offenders, offenders
