"""The FORBILD head phantom: its shapes' level functions, partial-volume sampling against analytic volumes, the
anatomy in LPS, determinism and noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from algorithms.datasets.forbild import (
    AIR_HU,
    Shape,
    ct_noise,
    forbild_head_array,
    forbild_shapes,
    grid_origin,
    coverage,
    point_values,
)


def _fraction_volume(values: np.ndarray, hu: float, spacing) -> float:
    """mm^3 of a single shape of value ``hu`` painted over air, from the sampled partial volumes."""
    fractions = (values.astype(np.float64) - AIR_HU) / (hu - AIR_HU)
    return float(fractions.sum() * np.prod(spacing))


def _tilted_frame(degrees_x: float, degrees_z: float) -> np.ndarray:
    a, b = math.radians(degrees_x), math.radians(degrees_z)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    return (rz @ rx).T  # rows: the local axes


@pytest.mark.parametrize(
    "shape, volume",
    [
        (Shape("ball", "ellipsoid", (1.3, -0.7, 0.4), (9.0, 9.0, 9.0), 1000.0), 4 / 3 * math.pi * 9.0**3),
        (Shape("ellipsoid", "ellipsoid", (0.0, 0.0, 0.0), (12.0, 7.0, 5.0), 1000.0, _tilted_frame(30, 50)),
         4 / 3 * math.pi * 12.0 * 7.0 * 5.0),
        (Shape("cylinder", "cylinder", (0.5, 0.0, 0.0), (8.0, 4.0, 9.0), 1000.0, _tilted_frame(40, 10)),
         math.pi * 8.0 * 4.0 * 18.0),
        (Shape("cone", "cone", (0.0, 0.0, 0.0), (9.0, 3.0, 10.0), 1000.0, _tilted_frame(70, 20)),
         math.pi * 20.0 / 3 * (9.0**2 + 9.0 * 3.0 + 3.0**2)),
        (Shape("half ellipsoid", "ellipsoid", (2.0, 0.0, 0.0), (14.0, 6.0, 6.0), 1000.0,
               clips=(((1.0, 0.0, 0.0), 2.0),)), 2 / 3 * math.pi * 14.0 * 6.0 * 6.0),
    ],
    ids=lambda value: value.name if isinstance(value, Shape) else "",
)
def test_partial_volumes_add_up_to_the_analytic_volume(shape, volume):
    """Sampled on a coarse anisotropic grid, the coverage fractions of one shape sum to its exact volume."""
    spacing = (1.1, 0.9, 1.7)
    grid = (28, 40, 40)
    values = forbild_head_array(grid, spacing, origin=grid_origin(grid, spacing, (0.0, 0.0, 0.0)), shapes=[shape])
    # int16 rounding of the fractions costs at most 0.5 HU in 2000 per voxel on the boundary layer
    assert _fraction_volume(values, shape.hu, spacing) == pytest.approx(volume, rel=4e-3)


def test_every_level_function_is_1_lipschitz():
    """The sampler skips voxels whose centre's |level| exceeds the half-diagonal; that is only right when every
    level function changes by at most the distance moved."""
    rng = np.random.default_rng(4)
    for shape in forbild_shapes():
        box = shape.bounds()
        low = np.maximum(box[0], -200.0)
        high = np.minimum(box[1], 200.0)
        p = rng.uniform(low - 3.0, high + 3.0, size=(400, 3))
        q = p + rng.normal(scale=rng.choice([0.05, 0.5, 4.0]), size=p.shape)
        change = np.abs(shape.level(p) - shape.level(q))
        assert np.all(change <= np.linalg.norm(p - q, axis=1) * (1 + 1e-9) + 1e-12), shape.name


def test_bounds_hold_their_shape():
    rng = np.random.default_rng(5)
    for shape in forbild_shapes():
        box = shape.bounds()
        low, high = np.maximum(box[0], -300.0), np.minimum(box[1], 300.0)
        margin = 0.25 * (high - low) + 1.0
        p = rng.uniform(low - margin, high + margin, size=(4000, 3))
        inside = shape.level(p) <= 0
        assert np.all((p[inside] >= box[0]) & (p[inside] <= box[1])), shape.name


def test_definition_counts():
    shapes = forbild_shapes(scalp=False, table=False)
    assert sum(s.name.startswith("air cell") for s in shapes) == 317
    assert sum(s.name.startswith("resolution rod") for s in shapes) == 144
    assert not any(s.addition for s in shapes)
    assert sum(s.addition for s in forbild_shapes()) == 4  # head rest, two table layers, scalp


@pytest.mark.parametrize(
    "point, hu, what",
    [
        ((30.0, -20.0, 40.0), 50.0, "brain (rho 1.05)"),
        ((0.0, 40.0, 10.0), 45.0, "ellipsoid 12 behind the centre (rho 1.045)"),
        ((47.0, -43.0, 8.72), 60.0, "eye 1, on the patient's left (x > 0) and anterior (y < 0)"),
        ((-47.0, -43.0, 8.72), 60.0, "eye 2, on the right"),
        ((0.0, -84.0, 0.0), -1000.0, "frontal sinus (air), anterior"),
        ((0.0, 0.0, 122.0), 800.0, "skull at the vertex (superior, z > 0)"),
        ((0.0, 0.0, 127.0), 40.0, "scalp over the vertex"),
        ((-80.0, 0.0, 0.0), -1000.0, "an air cell of the inner ear, on the patient's right (x < 0)"),
        ((-82.0, 0.0, 0.0), 800.0, "petrous bone between two air cells"),
        ((10.8, 90.0, 0.0), 52.5, "low-contrast sphere 3 (rho 1.0525), posterior"),
        ((-10.8, 90.0, 0.0), 47.5, "low-contrast sphere 4 (rho 1.0475)"),
        ((0.0, 140.0, 0.0), -900.0, "table core, behind the head (posterior)"),
        ((0.0, 133.0, 0.0), 200.0, "table top skin"),
        ((0.0, 128.0, 0.0), -900.0, "head rest between the scalp and the table"),
        ((0.0, -200.0, 0.0), -1000.0, "air in front of the face"),
    ],
)
def test_anatomy_lands_where_the_patient_is(point, hu, what):
    """The definition's RAS cm frame mapped to LPS mm: right ear at x < 0, face at y < 0, vertex at z > 0."""
    assert point_values(np.array(point)) == pytest.approx(hu), what


@pytest.mark.slow
def test_sampled_volume_matches_point_values_away_from_edges():
    spacing = (4.0, 4.0, 6.0)  # the field of view of the sample; coarse, so the check takes seconds
    grid = (44, 72, 56)
    values = forbild_head_array(grid, spacing)
    origin = np.asarray(grid_origin(grid, spacing))
    k, j, i = np.mgrid[0:grid[0], 0:grid[1], 0:grid[2]]
    centres = origin + np.stack([i, j, k], axis=-1) * np.asarray(spacing)
    exact = point_values(centres)
    half = 0.5 * math.hypot(*spacing)
    clear = np.ones(grid, bool)
    for shape in forbild_shapes():
        box = shape.bounds()
        near = np.all((centres >= box[0] - half) & (centres <= box[1] + half), axis=-1)
        clear[near] &= np.abs(shape.level(centres[near])) > half
    assert clear.mean() > 0.5
    np.testing.assert_array_equal(values[clear], np.rint(exact[clear]).astype(np.int16))
    # and near edges every value lies between the values of the phantom around it
    assert values.min() >= -1000 and values.max() <= 800


def test_coverage_of_a_half_space_is_exact_for_planes_through_sub_box_centres():
    """A plane x <= c with c on the sub-box grid: every box's coverage is exactly its share on the plane's side."""
    plane = Shape("slab", "ellipsoid", (0.0, 0.0, 0.0), (1e6, 1e6, 1e6), 1000.0, clips=(((1.0, 0.0, 0.0), 0.3),))
    centres = np.array([[0.3, 0.0, 0.0], [0.05, 5.0, 2.0], [-2.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.55, 0.0, 0.0]])
    fractions = coverage(plane, centres, (1.0, 1.0, 2.0))
    np.testing.assert_allclose(fractions, [0.5, 0.75, 1.0, 0.0, 0.25])


def test_deterministic_and_noise_has_the_asked_deviation():
    grid, spacing = (16, 40, 40), (7.0, 7.0, 17.0)
    a = forbild_head_array(grid, spacing, noise_hu=12.0, seed=3)
    b = forbild_head_array(grid, spacing, noise_hu=12.0, seed=3)
    c = forbild_head_array(grid, spacing, noise_hu=12.0, seed=4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    noise = ct_noise((40, 200, 200), 12.0, seed=1)
    interior = noise[:, 2:-2, 2:-2]
    assert abs(float(interior.std()) - 12.0) < 0.3 and abs(float(interior.mean())) < 0.2
    # correlated in-plane (a reconstruction kernel's texture), not across slices
    assert np.corrcoef(interior[:, :, :-1].ravel(), interior[:, :, 1:].ravel())[0, 1] > 0.5
    assert abs(np.corrcoef(interior[:-1].ravel(), interior[1:].ravel())[0, 1]) < 0.02


def test_bad_grids_are_refused():
    with pytest.raises(ValueError, match="positive sizes"):
        forbild_head_array((0, 4, 4), (1, 1, 1))
    with pytest.raises(ValueError, match="spacing"):
        forbild_head_array((4, 4, 4), (1, 0, 1))
