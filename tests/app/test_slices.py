"""Slice geometry: standard frames, voxel-exact axis-aligned slices, oblique reformatting of an analytic field, the
crosshair rotation, and the planes' outlines in 3D."""

from __future__ import annotations

import numpy as np
import pytest

from app.slices import (
    crosshair_lines,
    plane_frame,
    plane_grid,
    plane_outline,
    rotation_about,
    sample_plane,
    slice_frames,
    value_at,
)
from app.volume import Volume
from app.workbench import WorkbenchModel


def _ramp(shape=(20, 30, 40), spacing=(0.8, 1.1, 1.5), direction=None):
    """A volume whose value is an affine function of the LPS position: trilinear sampling reproduces it exactly."""
    volume = Volume(np.zeros(shape, np.float32), spacing=spacing, origin=(-10.0, 5.0, 30.0),
                    direction=np.eye(3) if direction is None else direction)
    nz, ny, nx = shape
    k, j, i = np.mgrid[0:nz, 0:ny, 0:nx]
    world = volume.index_to_world(np.stack([i, j, k], axis=-1))
    volume.array = (2.0 * world[..., 0] - 3.0 * world[..., 1] + 0.5 * world[..., 2]).astype(np.float32)
    return volume


def _field(points):
    return 2.0 * points[..., 0] - 3.0 * points[..., 1] + 0.5 * points[..., 2]


def test_standard_frames_follow_the_radiological_convention():
    labels = {plane: frame.labels() for plane, frame in slice_frames().items()}
    assert labels["axial"] == {"right": "L", "left": "R", "top": "A", "bottom": "P"}
    assert labels["coronal"] == {"right": "L", "left": "R", "top": "S", "bottom": "I"}
    assert labels["sagittal"] == {"right": "P", "left": "A", "top": "S", "bottom": "I"}
    for frame in slice_frames().values():
        np.testing.assert_allclose(np.cross(frame.u, frame.v), frame.n)
        assert not frame.oblique


@pytest.mark.parametrize("order", [0, 1])
@pytest.mark.parametrize("plane", ["axial", "coronal", "sagittal"])
def test_axis_aligned_slices_are_the_stored_voxels(plane, order):
    rng = np.random.default_rng(3)
    volume = Volume(rng.integers(0, 1000, (12, 17, 23)).astype(np.int16), spacing=(0.7, 1.3, 2.0),
                    origin=(4.0, -8.0, 1.0))
    cursor = volume.index_to_world((5, 9, 4))
    grid = plane_grid(volume, plane_frame(plane), cursor)
    image = sample_plane(volume, grid, order=order)
    # Axial: rows run anterior (j = 0) to posterior, columns right to left (i = 0..); coronal: rows superior (k
    # last) down; sagittal: columns anterior to posterior (j), rows superior down.
    expected = {"axial": volume.array[4], "coronal": volume.array[::-1, 9, :], "sagittal": volume.array[::-1, :, 5]}
    np.testing.assert_allclose(image, expected[plane], atol=1e-3 if order else 0)


def test_oblique_reformat_of_an_affine_field_is_exact():
    volume = _ramp()
    model_rotation = rotation_about((0, 0, 1), 30.0) @ rotation_about((1, 0, 0), 20.0)
    cursor = volume.centre + np.array([1.3, -2.1, 0.7])
    for plane in ("axial", "coronal", "sagittal"):
        frame = plane_frame(plane, model_rotation)
        assert frame.oblique
        grid = plane_grid(volume, frame, cursor)
        image = sample_plane(volume, grid, order=1)
        points = grid.points()
        inside = np.isfinite(image)
        index = volume.world_to_index(points[inside])
        strictly = np.all((index >= 0) & (index <= np.asarray(volume.dimensions) - 1), axis=1)
        assert strictly.sum() > 200
        np.testing.assert_allclose(image[inside][strictly], _field(points[inside][strictly]), rtol=1e-5, atol=1e-3)
        # the plane goes through the cursor
        assert abs(float((grid.to_world(*grid.to_plane(cursor)) - cursor) @ frame.n)) < 1e-9


def test_rotating_the_crosshair_in_the_axial_view_tilts_the_two_other_planes():
    model = WorkbenchModel()
    model.set_volume(_ramp())
    model.rotate_slices("axial", 30.0)
    frames = slice_frames(model.slice_rotation)
    np.testing.assert_allclose(frames["axial"].n, [0, 0, -1], atol=1e-12)  # the axial view keeps its picture
    np.testing.assert_allclose(frames["axial"].u, [1, 0, 0], atol=1e-12)
    angle = np.degrees(np.arccos(abs(frames["coronal"].n @ np.array([0.0, 1.0, 0.0]))))
    assert angle == pytest.approx(30.0, abs=1e-9)
    # In the axial view the coronal line turned by 30 degrees, counter-clockwise on screen.
    du, dv = crosshair_lines("axial", model.slice_rotation)["coronal"]
    assert np.degrees(np.arctan2(dv, du)) % 180 == pytest.approx(30.0, abs=1e-9)
    with pytest.raises(ValueError, match="plane must be one of"):
        model.rotate_slices("oblique", 5)
    with pytest.raises(ValueError, match="rotation matrix"):
        model.set_slice_rotation(np.diag([1.0, 1.0, -1.0]))


def test_plane_outline_lies_in_the_plane_and_on_the_box():
    volume = _ramp()
    cursor = volume.centre
    frame = plane_frame("coronal", rotation_about((0, 0, 1), 25.0))
    outline = plane_outline(volume, frame, cursor)
    assert len(outline) == 4
    np.testing.assert_allclose((outline - cursor) @ frame.n, 0.0, atol=1e-9)
    low, high = np.asarray(volume.world_bounds[0::2]), np.asarray(volume.world_bounds[1::2])
    assert np.all(outline >= low - 1e-9) and np.all(outline <= high + 1e-9)
    assert len(plane_outline(volume, frame, cursor + 1e4 * frame.n)) == 0


def test_value_at_outside_is_none():
    volume = _ramp()
    assert value_at(volume, volume.centre + 1e4) is None
    corner = volume.index_to_world((0, 0, 0))
    assert value_at(volume, corner) == pytest.approx(float(volume.array[0, 0, 0]))
