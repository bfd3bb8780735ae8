"""The import layering ui -> app -> algorithms, and no Qt below ui, checked by import-linter's contracts."""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def lint(directory: Path) -> subprocess.CompletedProcess:
    lint_imports = Path(sys.executable).with_name("lint-imports")
    return subprocess.run([str(lint_imports), "--config", str(directory / "pyproject.toml"), "--no-cache"],
                          cwd=directory, capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(directory), "PATH": str(lint_imports.parent)})


def test_contracts_hold_for_the_project():
    result = lint(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "2 kept, 0 broken" in result.stdout


@pytest.mark.parametrize(
    "module, source, broken",
    [
        ("algorithms/bad.py", "import app.volume\n", "Layers"),
        ("app/bad.py", "import qtpy\n", "never import Qt"),
        ("app/bad.py", "from ui import window\n", "Layers"),
    ],
)
def test_contracts_catch_violations(tmp_path, module, source, broken):
    """The same contracts, applied to a tiny copy of the layout with one forbidden import, must fail."""
    for package in ("algorithms", "app", "ui"):
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
    (tmp_path / "ui" / "window.py").write_text("import app\n")
    (tmp_path / "qtpy").mkdir()
    (tmp_path / "qtpy" / "__init__.py").write_text("")
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    (tmp_path / module).write_text(textwrap.dedent(source))
    result = lint(tmp_path)
    assert result.returncode != 0
    assert "BROKEN" in result.stdout and broken in result.stdout
