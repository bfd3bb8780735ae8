"""The workbench model's issue-18 additions without a window: presets and window/level per modality, undo of
isovalue and transfer-function edits, the tight camera, provenance of a damaged DICOM folder, the series that cannot
be opened, and sessions written and read back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.datasets import ct_head_phantom
from app.framing import content_bounds, tight_camera
from app.io import load_volume, write_dicom_series
from app.measurements import Measurement
from app.provenance import provenance, series_choices
from app.session import apply_model_state, model_state, read_session, write_session
from app.volume import Volume
from app.workbench import WorkbenchModel, presets_for, window_presets

from .dicom_helpers import small_ct


def _mr() -> Volume:
    values = np.random.default_rng(1).gamma(4.0, 30.0, (20, 30, 30)).astype(np.float32)
    return Volume(values, modality="MR")


def test_presets_and_windows_follow_the_modality():
    ct, mr = ct_head_phantom(shape=(22, 52, 52), spacing=(5.0, 5.0, 10.0)), _mr()
    assert "ct-bone" in presets_for(ct) and "ct-bone" not in presets_for(mr) and "mr-default" in presets_for(mr)
    assert "Bone" in window_presets(ct)
    auto = window_presets(mr)["Automatic (0.5-99.5 %)"]
    lo, hi = mr.percentile_range(0.5, 99.5)
    assert auto == pytest.approx((hi - lo, (hi + lo) / 2))
    model = WorkbenchModel()
    model.set_volume(mr)
    notices = []
    model.notice.connect(notices.append)
    with pytest.raises(ValueError, match="made for HU values"):
        model.set_preset("ct-bone")
    model.set_preset("ct-bone", force=True)
    assert model.preset == "ct-bone" and "CT preset" in model.preset_warning() and "CT" in notices[0]


def test_undo_restores_isovalue_and_transfer_function():
    model = WorkbenchModel()
    model.set_volume(ct_head_phantom(shape=(22, 52, 52), spacing=(5.0, 5.0, 10.0)))
    changes = []
    model.undoable.connect(changes.append)
    original = model.transfer_function
    model.set_opacity_points([(-1024, 0.0), (100, 0.0), (600, 0.9)])
    model.set_iso(150.0)
    assert [c.label for c in changes] == ["Opacity points", "Isovalue 300 -> 150 HU"]
    changes[1].undo()
    changes[0].undo()
    assert model.iso == 300.0 and model.transfer_function == original
    changes[0].redo()
    assert model.transfer_function.opacity_points[-1] == (600.0, 0.9)
    cleared = []
    model.history_cleared.connect(lambda: cleared.append(True))
    model.set_volume(_mr())
    assert cleared


def test_tight_camera_frames_the_visible_object():
    volume = ct_head_phantom(shape=(40, 64, 64), spacing=(3.0, 3.0, 5.0))
    bounds = content_bounds(volume, 300.0)
    whole = volume.world_bounds
    assert all(bounds[2 * a + 1] - bounds[2 * a] <= whole[2 * a + 1] - whole[2 * a] + max(volume.spacing) + 1e-6
               for a in range(3))
    camera = tight_camera(bounds, view="anterior", aspect=1.0)
    # Every corner of the box is in view, and one of them touches the (margined) edge of the field of view.
    corners = np.array([[x, y, z] for x in bounds[:2] for y in bounds[2:4] for z in bounds[4:]])
    position, focal = np.asarray(camera.position), np.asarray(camera.focal_point)
    forward = (focal - position) / np.linalg.norm(focal - position)
    up = np.asarray(camera.view_up)
    right = np.cross(forward, up)
    depth = (corners - position) @ forward
    tangents = np.maximum(np.abs((corners - position) @ right), np.abs((corners - position) @ up)) / depth
    half = np.tan(np.radians(camera.view_angle / 2))
    assert tangents.max() <= half + 1e-9 and tangents.max() > 0.9 * half
    assert content_bounds(volume, 1e9) is None


def test_provenance_lists_every_warning_of_a_damaged_folder(tmp_path):
    volume = small_ct()
    paths = write_dicom_series(volume, tmp_path / "damaged", rescale_intercept=-1024, description="HEAD")
    paths[5].unlink()  # a missing slice, filled by interpolation
    truncated = paths[0]
    truncated.write_bytes(truncated.read_bytes()[:-500])
    (tmp_path / "damaged" / "notes.txt").write_text("scanned on Tuesday")
    loaded = load_volume(tmp_path / "damaged")
    info = provenance(loaded)
    assert info["warnings"] == loaded.metadata["warnings"] and len(info["warnings"]) >= 3
    assert "invented by linear interpolation" in info["alerts"][0] and info["geometry"]["interpolated_slices"] == 1
    assert info["dicom"]["PatientID"] == "VOXELSCOPE-0001" and info["dicom"]["SeriesDescription"] == "HEAD"
    assert info["source"]["files_used"] == len(paths) - 2
    json.dumps(info)


def test_single_image_series_cannot_be_chosen():
    choices = series_choices([{"series_uid": "a", "slices": 40, "rows": 64, "columns": 64, "volumes": 1},
                              {"series_uid": "b", "slices": 1, "rows": 512, "columns": 512, "volumes": 1}])
    assert [c["loadable"] for c in choices] == [True, False] and "single image" in choices[1]["reason"]


def test_session_round_trip(tmp_path):
    from app.io import save_volume

    path = save_volume(ct_head_phantom(shape=(22, 52, 52), spacing=(5.0, 5.0, 10.0)), tmp_path / "head.nii.gz")
    model = WorkbenchModel()
    model.set_volume(load_volume(path))
    model.set_layout("1x2")
    model.set_view_mode(1, "raymarch", {"samples": 20})
    model.set_iso(500.0)
    model.set_opacity_points([(-1024, 0.0), (100, 0.0), (600, 0.9)])
    model.rotate_slices("coronal", 12.0)
    model.add_measurement(Measurement("distance", points=[(0, 0, 0), (3, 4, 0)]))
    state = model_state(model)
    session = write_session(tmp_path / "s.voxelscope.json", state)
    with pytest.raises(Exception, match="already exists"):
        write_session(session, state)

    restored = WorkbenchModel()
    loaded = read_session(session)
    restored.set_volume(load_volume(loaded["data"]["volume"]["path"]))
    apply_model_state(restored, loaded)
    assert restored.layout == "1x2" and restored.view_modes[1] == "raymarch"
    assert restored.view_options[1] == {"samples": 20} and restored.iso == 500.0
    assert restored.transfer_function == model.transfer_function
    np.testing.assert_allclose(restored.slice_rotation, model.slice_rotation)
    assert [m.results["value"] for m in restored.measurements] == [pytest.approx(5.0)]

    (tmp_path / "bad.json").write_text('{"format": "something else"}')
    with pytest.raises(ValueError, match="not a Voxelscope session"):
        read_session(tmp_path / "bad.json")
    state["data"]["volume"]["path"] = str(tmp_path / "gone.nii.gz")
    write_session(tmp_path / "gone.json", state)
    with pytest.raises(ValueError, match="no longer there"):
        read_session(tmp_path / "gone.json")
