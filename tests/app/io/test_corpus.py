"""Every test file shipped in the pydicom, pydicom-data and nibabel wheels: it loads, or our one-line error says why.

Non-image objects (RT plans, structured reports, ...), 2D images, tractography files and formats Voxelscope does
not read must be refused with a :class:`VolumeReadError` naming the file; nothing may raise anything else, crash,
hang or run away with memory (each file is loaded in the fuzz harness's worker process).
"""

from __future__ import annotations

import json
from collections import Counter

import pytest

from app.io import list_series

from .corpus import corpus_roots, prepare
from .fuzz import run_variants, summary


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    variants = prepare(tmp_path_factory.mktemp("corpus"))
    if not variants:
        pytest.skip("none of the pydicom, pydicom-data or nibabel wheels is installed")
    return variants


def test_every_real_file_loads_or_is_refused_in_one_line(corpus):
    outcomes = run_variants(corpus, timeout=120)
    report = summary(outcomes)
    print("\nreal-file corpora:", json.dumps(report["per_format"], sort_keys=True))
    reasons = Counter(o.message.split(": ", 1)[-1][:70] for o in outcomes if o.status == "refused")
    print("\n".join(f"{count:4d}  {reason}" for reason, count in reasons.most_common(25)))
    assert not report["broken"], report["broken"]
    assert not [o.variant.name for o in outcomes if o.unexpected]
    assert {o.status for o in outcomes} <= {"loaded", "refused"}
    loaded = {o.variant.name for o in outcomes if o.status == "loaded"}
    # The volumes among them do load: multi-frame RT dose and enhanced CT, MOSAIC, Philips enhanced MR, NIfTI, MINC.
    for name in ("pydicom/test_files/rtdose.dcm", "pydicom-data/eCT_Supplemental.dcm", "nibabel/nicom/tests/data/0.dcm",
                 "nibabel/nicom/tests/data/philips_mprage.dcm.gz (inflated)", "nibabel/tests/data/example4d.nii.gz",
                 "nibabel/tests/data/minc2_4d.mnc", "nibabel/tests/data/small.mnc"):
        if name.split("/")[0] in corpus_roots():
            assert name in loaded, name


def test_non_image_objects_are_listed_as_no_series(corpus):
    plans = [v for v in corpus if v.path.name in ("rtplan.dcm", "rtstruct.dcm", "test-SR.dcm")]
    assert plans
    for variant in plans:
        assert list_series(variant.path.parent) == []
