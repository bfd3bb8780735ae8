"""The readers' contract on damaged files (see :mod:`tests.app.io.fuzz`): in-process loads and the command line.

The default run checks every third variant of the fixed-seed set and three command lines; the long run
(``-m long_fuzz``) checks all variants, two more seeds, and a sample through ``voxelscope info``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from .fuzz import generate, run_cli, run_variants, summary

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="the harness uses /proc and RLIMIT_AS (Linux)")


@pytest.fixture(scope="module")
def variants(tmp_path_factory):
    return generate(tmp_path_factory.mktemp("fuzz"))


def _check(outcomes, label: str) -> dict:
    report = summary(outcomes)
    print(f"\n{label}: {report['total']} runs")
    print(json.dumps(report["per_format"], indent=1, sort_keys=True))
    assert not report["broken"], "\n".join(f"{name}: {problems}: {message}" for name, problems, message in report["broken"])
    unexpected = [(o.variant.name, o.message) for o in outcomes if o.unexpected]
    assert not unexpected, f"errors only the last line of defence caught: {unexpected}"
    return report


def test_generator_covers_every_format_and_kind(variants):
    formats = {v.fmt for v in variants}
    assert formats == {"DICOM", "NIfTI", "NRRD", "MetaImage", "VTI", "VTK legacy"}
    kinds = {(v.fmt, v.kind) for v in variants}
    assert all((fmt, kind) in kinds for fmt in formats for kind in ("flip", "cut", "lie", "special"))
    assert len(variants) > 600
    names = [v.name for v in variants]
    assert len(set(names)) == len(names)
    for expected in ("nifti/dims-32767^3", "nifti2/dims-2^40", "nifti/datatype-999", "nifti/vox-offset-0",
                     "mha-raw/dimsize-1e5^3", "mhd-header/compressed-size-1e12", "vti-raw/extent-1e5^3",
                     "nhdr-header/data-fifo", "nhdr-header/data-dev-zero", "nhdr-header/line-skip-1e9",
                     "nifti-gz/crc-error", "nifti-gz/bomb-16GiB", "mhd-zraw/data-list"):
        assert expected in names


def test_damaged_files_keep_the_contract(variants):
    _check(run_variants(variants[::3]), "damaged files, every third variant")


def test_command_line_on_damaged_files(variants):
    chosen = [v for v in variants if v.name in ("nifti/dims-32767^3", "mha-raw/dimsize-1e5^3", "nhdr-header/data-fifo")]
    outcomes = run_cli(chosen)
    _check(outcomes, "voxelscope info")
    for outcome in outcomes:
        assert outcome.status == "refused" and outcome.message.count("\n") == 0
        assert outcome.message.startswith("voxelscope: error: ")


@pytest.mark.long_fuzz
def test_all_damaged_files_keep_the_contract(variants):
    _check(run_variants(variants), "damaged files, all variants (seed 20)")


@pytest.mark.long_fuzz
@pytest.mark.parametrize("seed", [1, 2])
def test_more_seeds(tmp_path, seed):
    _check(run_variants(generate(tmp_path, seed=seed)), f"damaged files, seed {seed}")


@pytest.mark.long_fuzz
def test_command_line_on_a_sample(variants):
    _check(run_cli(variants[::11]), "voxelscope info, every 11th variant")


def test_outcomes_are_judged_strictly(tmp_path):
    """The judge itself: a silently loaded damaged payload, a multi-line or anonymous message are failures."""
    from .fuzz import Outcome, Variant

    damaged = Variant("x/cut", "NIfTI", "cut", Path("v.nii"), True, names=("v.nii",))
    assert Outcome(damaged, "loaded").problems == ["damaged data accepted silently"]
    assert Outcome(damaged, "refused", "v.nii: truncated").problems == []
    assert "multi-line message" in Outcome(damaged, "refused", "v.nii: a\nb").problems
    assert "message names no file" in Outcome(damaged, "refused", "truncated").problems
    dicom = Variant("d/cut", "DICOM", "cut", Path("d"), True, damaged_file="s2.dcm", names=("s2.dcm",))
    assert Outcome(dicom, "loaded", warnings=["d/s2.dcm: skipped, truncated"]).problems == []
    assert Outcome(dicom, "crash", "worker exit -6").problems == ["crash"]
