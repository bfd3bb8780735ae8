"""Operations make new scene items from others; the registry lists them with their inputs and options."""

from __future__ import annotations

import numpy as np
import pytest

from app.datasets import ct_head_phantom
from app.operations import get_operation, operations
from app.scene import FieldItem, Scene, VolumeItem
from app.volume import Volume


@pytest.fixture(scope="module")
def head():
    return VolumeItem("head", volume=ct_head_phantom(shape=(30, 64, 64), spacing=(3.75, 3.75, 7.2)))


def test_extract_surface_makes_a_mesh_in_patient_coordinates(head):
    operation = get_operation("extract-surface")
    assert "extract-surface" in [op.name for op in operations()]
    result = operation.run({"volume": head}, operation.resolve_options({"method": "marching-cubes"}))
    mesh = result.item
    assert mesh.kind == "mesh" and result.report["triangles"] > 1000 and result.report["iso"] == 300.0
    # LPS mm: the skull lies inside the volume's world bounds.
    low, high = np.array(mesh.bounds[0::2]), np.array(mesh.bounds[1::2])
    world = np.array(head.volume.world_bounds)
    assert np.all(low >= world[0::2] - 1e-3) and np.all(high <= world[1::2] + 1e-3)
    assert mesh.describe()["closed"] is False  # the neck leaves the volume at the bottom slice


def test_extract_surface_refuses_an_empty_surface_and_unknown_methods(head):
    operation = get_operation("extract-surface")
    with pytest.raises(ValueError, match="no surface at 5000 HU, which is above the largest value"):
        operation.run({"volume": head}, operation.resolve_options({"iso": 5000}))
    with pytest.raises(ValueError, match="--method must be one of"):
        operation.resolve_options({"method": "raymarch"})


def test_fields_use_their_own_level_and_inputs_are_checked():
    sphere = np.zeros((20, 20, 20), np.uint8)
    k, j, i = np.ogrid[:20, :20, :20]
    sphere[(i - 9.5) ** 2 + (j - 9.5) ** 2 + (k - 9.5) ** 2 <= 36] = 1
    mask = FieldItem("ball", volume=Volume(sphere), role="mask")
    operation = get_operation("extract-surface")
    result = operation.run({"volume": mask}, operation.resolve_options({}))
    assert result.report["iso"] == 0.5 and result.report["triangles"] > 100
    scene = Scene()
    scene.add(result.item)
    with pytest.raises(ValueError, match="'volume' must be a volume or field"):
        operation.check_inputs({"volume": result.item})
    with pytest.raises(ValueError, match="needs an input 'volume'"):
        operation.check_inputs({})
