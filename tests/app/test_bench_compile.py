"""``voxelscope bench compile`` on one kernel group, through the benchmark's own machinery: a cold process on an
empty cache folder, then a cached process on the same folder.

What is checked is what caching means, not speed (no wall-clock time is asserted): the cold process compiles our
marching-cubes kernels in its first call (numba's ``numba:compile`` events) and writes cache files (``*.nbi``,
``*.nbc``) into the folder it was given; the cached process compiles none of our kernels and loads them from there.
The files the benchmark writes are checked on that same measurement.
"""

from __future__ import annotations

import csv
import json
import math

import pytest

import app.bench.compile as bench_compile
from app.bench import BENCHMARKS
from app.cli import main

GROUP = "marching-cubes"
KERNEL = "algorithms.surfaces.marching_cubes.kernels.fill_layers"


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """One cold and one cached process of this checkout running the marching-cubes group; the cache folder."""
    cache = tmp_path_factory.mktemp("kernel-cache")
    return bench_compile.cold_and_cached(bench_compile.ROOT, [GROUP], cache), cache


@pytest.mark.slow
def test_the_cold_process_compiles_our_kernels_in_its_first_call(measured):
    run, _ = measured
    group = run["cold"]["groups"][0]
    assert group["group"] == GROUP and "error" not in group
    assert set(group["compiles"]) == {"setup", "first", "second"}
    assert all(group[f"{phase}_s"] >= 0 for phase in ("setup", "first", "second"))
    compiled = bench_compile.project_compiles(group["compiles"]["first"])
    assert KERNEL in compiled
    for entry in compiled.values():
        assert entry["inclusive_s"] >= entry["self_s"] >= 0
        assert entry["events"] == len(entry["signatures"]) >= 1
    # Imports and inputs compile nothing of ours, and the second call runs what the first compiled.
    assert bench_compile.project_compiles(group["compiles"]["setup"]) == {}
    assert bench_compile.project_compiles(group["compiles"]["second"]) == {}
    # The CT volume is int16: the kernel was compiled for it, and for nothing else.
    assert [s.startswith("(array(int16, 3d, C)") for s in compiled[KERNEL]["signatures"]] == [True]


@pytest.mark.slow
def test_the_cold_process_writes_the_cache_into_the_folder_it_was_given(measured):
    run, cache = measured
    assert run["cache_files"]["nbi"] >= 1 and run["cache_files"]["nbc"] >= 1
    index_files = sorted(path.name for path in cache.rglob("*.nbi"))
    assert any(name.startswith("kernels.fill_layers-") for name in index_files), index_files


@pytest.mark.slow
def test_the_cached_process_compiles_none_of_our_kernels_and_loads_them(measured):
    run, _ = measured
    cold, cached = run["cold"]["groups"][0], run["cached"]["groups"][0]
    assert "error" not in cached
    for phase in cached["compiles"].values():
        assert bench_compile.project_compiles(phase) == {}
    loaded = cached["signatures"]
    assert KERNEL in loaded and loaded[KERNEL]["cache_hits"] >= 1
    assert all(entry["cache_hits"] >= 1 for entry in loaded.values())
    for name, entry in loaded.items():
        assert entry["signatures"] == cold["signatures"][name]["signatures"]


@pytest.mark.slow
def test_the_benchmark_writes_its_tables_plot_and_json(measured, tmp_path, monkeypatch, capsys):
    """run() on the measurement above (its processes replaced by it), against this same checkout."""
    run, _ = measured
    monkeypatch.setattr(bench_compile, "cold_and_cached", lambda checkout, names, cache_dir=None: run)
    written = bench_compile.run(tmp_path, quick=True, groups=[GROUP], against=str(bench_compile.ROOT))
    assert sorted(path.name for path in written) == ["compile.csv", "compile.json", "compile.png", "kernels.csv"]
    assert (tmp_path / "compile.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    with open(tmp_path / "compile.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    keys = {(row["checkout"], row["group"]) for row in rows}
    assert keys == {(label, group) for label in ("this", "against")
                    for group in (GROUP, bench_compile.ALL, bench_compile.TOTAL)}
    for row in rows:
        cold, warm, compiled = (float(row[k]) for k in ("cold_first_s", "warm_second_s", "compile_s"))
        assert math.isclose(compiled, cold - warm, rel_tol=1e-4, abs_tol=1e-5)
        assert row["repeats"] == "1" and row["error"] == ""
    mine = next(row for row in rows if row["checkout"] == "this" and row["group"] == GROUP)
    assert int(mine["project_kernels_compiled"]) >= 3 and mine["cached_project_compiles"] == "0"

    with open(tmp_path / "kernels.csv", newline="") as handle:
        kernels = list(csv.DictReader(handle))
    ours = {row["kernel"]: row for row in kernels if row["checkout"] == "this" and row["group"] == GROUP}
    assert ours[KERNEL]["project"] == "True" and int(ours[KERNEL]["signature_count"]) == 1
    assert "int16" in ours[KERNEL]["signatures"]

    report = json.loads((tmp_path / "compile.json").read_text())
    assert {"machine", "numba", "command_line", "checkouts", "groups", "samples"} <= set(report)
    assert set(report["checkouts"]) == {"this", "against"}
    assert set(report["checkouts"]["this"]) == {"path", "commit", "modified"}
    assert (report["checkouts"]["this"]["commit"] or "").startswith(mine["commit"])  # the CSV's is shortened
    table = capsys.readouterr().out
    assert GROUP in table and "this/against" in table


def test_the_compile_benchmark_is_registered():
    assert BENCHMARKS["compile"] == "app.bench.compile"
    assert set(bench_compile.GROUPS) >= {"marching-cubes", "raymarch", "shear-warp", "texture-slicing",
                                         "voxel-surfaces", "cutaway", "voxelise", "winding", "distance", "csg",
                                         "isosurface-stuffing"}


def test_against_is_refused_by_a_benchmark_that_measures_one_checkout(tmp_path, capsys):
    assert main(["bench", "memory", "-o", str(tmp_path / "out"), "--against", str(tmp_path)]) == 1
    assert "--against" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_an_unknown_group_or_a_folder_that_is_no_checkout_is_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown compile groups"):
        bench_compile.run(tmp_path, groups=["no-such-group"])
    with pytest.raises(ValueError, match="no checkout"):
        bench_compile.run(tmp_path, groups=[GROUP], against=str(tmp_path))
