"""Measurements: distances and angles with analytic answers, ellipse and mask statistics against NumPy on the same
voxels, CSV and stored form, and undo through the model."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from app.measurements import Measurement, MeasurementList, angle_degrees, distance_mm
from app.scene import FieldItem
from app.slices import plane_frame
from app.volume import Volume
from app.workbench import WorkbenchModel


def _volume():
    rng = np.random.default_rng(5)
    return Volume(rng.normal(40.0, 12.0, (16, 40, 50)).astype(np.float32), spacing=(0.6, 0.8, 2.5),
                  origin=(-15.0, -16.0, 20.0), units="HU", modality="CT")


def test_distance_and_angle():
    assert distance_mm((0, 0, 0), (3, 4, 12)) == pytest.approx(13.0)
    assert angle_degrees((1, 0, 0), (0, 0, 0), (1, 1, 0)) == pytest.approx(45.0)
    assert angle_degrees((5, 0, 0), (2, 2, 2), (2, 2, 9)) == pytest.approx(
        np.degrees(np.arccos(np.dot([3, -2, -2], [0, 0, 7]) / (np.sqrt(17) * 7))))
    with pytest.raises(ValueError, match="two points apart from its vertex"):
        angle_degrees((0, 0, 0), (0, 0, 0), (1, 0, 0))
    with pytest.raises(ValueError, match="needs 3 point"):
        Measurement("angle", points=[(0, 0, 0), (1, 1, 1)])


@pytest.mark.parametrize("plane", ["axial", "coronal", "sagittal"])
def test_ellipse_statistics_match_numpy_on_the_same_voxels(plane):
    volume = _volume()
    frame = plane_frame(plane)
    centre = volume.index_to_world((27, 18, 7)) + 0.2 * frame.u  # slightly off a voxel centre, in the plane
    radii = (6.0, 4.5)
    measurement = Measurement("ellipse", points=[centre], plane=plane, frame=[frame.u.tolist(), frame.v.tolist()],
                              radii=list(radii))
    result = measurement.compute(volume)
    # NumPy on the voxels of the slice through the centre whose centres lie inside the ellipse.
    nz, ny, nx = volume.array.shape
    k, j, i = np.mgrid[0:nz, 0:ny, 0:nx]
    world = volume.index_to_world(np.stack([i, j, k], axis=-1))
    d = world - centre
    in_slice = np.abs(d @ frame.n) < 0.5 * np.abs(frame.n) @ np.asarray(volume.spacing)
    inside = in_slice & (((d @ frame.u) / radii[0]) ** 2 + ((d @ frame.v) / radii[1]) ** 2 <= 1.0)
    values = volume.array[inside].astype(np.float64)
    assert result["pixels"] == values.size > 10
    assert result["mean"] == pytest.approx(values.mean(), rel=1e-6)
    assert result["sd"] == pytest.approx(values.std(), rel=1e-5)
    assert (result["min"], result["max"]) == (pytest.approx(values.min()), pytest.approx(values.max()))
    pixel_area = float(np.prod([s for s, n in zip(volume.spacing, np.abs(frame.n)) if n < 0.5]))
    assert result["value"] == pytest.approx(values.size * pixel_area) and result["unit"] == "mm^2"
    assert result["value_units"] == "HU"


def test_mask_statistics_resample_the_mask_onto_the_volume():
    volume = _volume()
    mask = np.zeros(volume.array.shape, np.uint8)
    mask[3:9, 10:25, 5:30] = 1
    coarse = Volume(mask, spacing=volume.spacing, origin=volume.origin)
    result = Measurement("mask", mask="roi").compute(volume, mask_volume=coarse)
    values = volume.array[mask == 1]
    assert result["mean"] == pytest.approx(values.mean(), rel=1e-6) and result["pixels"] == values.size
    assert result["value"] == pytest.approx(values.size * 0.6 * 0.8 * 2.5) and result["unit"] == "mm^3"


def test_csv_and_stored_form_round_trip(tmp_path):
    items = MeasurementList()
    first = items.add(Measurement("distance", points=[(0, 0, 0), (0, 3, 4)]))
    first.compute()
    assert first.name == "Distance 1"
    rows = list(csv.DictReader(io.StringIO(items.to_csv())))
    assert rows[0]["kind"] == "distance" and float(rows[0]["value"]) == pytest.approx(5.0) and rows[0]["unit"] == "mm"
    path = items.write_csv(tmp_path / "m.csv")
    assert path.read_text() == items.to_csv()
    with pytest.raises(Exception, match="already exists"):
        items.write_csv(tmp_path / "m.csv")
    again = Measurement.from_dict(first.to_dict())
    assert again.points == first.points and again.results == first.results
    with pytest.raises(ValueError, match="kind must be one of"):
        Measurement.from_dict({"kind": "area"})


def test_model_measurements_are_undoable():
    model = WorkbenchModel()
    model.set_volume(_volume())
    changes = []
    model.undoable.connect(changes.append)
    measurement = model.add_measurement(Measurement("distance", points=[(0, 0, 30), (6, 8, 30)]))
    assert measurement.results["value"] == pytest.approx(10.0) and len(model.measurements) == 1
    changes[-1].undo()
    assert len(model.measurements) == 0
    changes[-1].redo()
    assert list(model.measurements) == [measurement]
    assert len(changes) == 1  # undo and redo are not recorded as new edits
    field = FieldItem("roi", volume=model.base_volume.with_array((model.base_volume.array > 40).astype(np.uint8)),
                      role="mask")
    model.scene.add(field)
    stats = model.add_measurement(Measurement("mask", mask="roi"))
    assert stats.results["mean"] > 40
