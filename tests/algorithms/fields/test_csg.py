"""CSG on signed distance fields (source 002, section 3.3.1): union, intersection and difference of meshes'
distance fields against analytic solids (two spheres: their lens), smooth blends, a volume's isosurface as a field,
and the meshed result (closed, outward)."""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.common.grid import Grid
from algorithms.compare.measures import enclosed_volume
from algorithms.compare.topology import edge_manifoldness, orientation_outward
from algorithms.fields.csg import combine, isosurface_field
from app.operations.distance import mesh_field
from algorithms.fields.distance import signed_distance

from ._voxelise_shapes import sphere, torus

R1, R2, GAP = 20.0, 15.0, 22.0  # two spheres, centres GAP mm apart along x


def _lens(r1, r2, d):
    return np.pi * (r1 + r2 - d) ** 2 * (d * d + 2 * d * r2 - 3 * r2 * r2 + 2 * d * r1 + 6 * r1 * r2 - 3 * r1 * r1) \
        / (12 * d)


@pytest.fixture(scope="module")
def two_spheres():
    a = sphere(R1, around=256, across=128)
    b = sphere(R2, around=256, across=128, centre=(GAP, 0.0, 0.0))
    grid = Grid.around((-R1, GAP + R2, -R1, R1, -R1, R1), spacing=0.6, padding=4)
    fa = signed_distance(*a, grid, band_mm=3.0, outside="propagate")
    fb = signed_distance(*b, grid, band_mm=3.0, outside="propagate")
    return grid, fa.values, fb.values


def _ball(r):
    return 4.0 / 3.0 * np.pi * r ** 3


@pytest.mark.parametrize(("operation", "expected"), [
    ("union", _ball(R1) + _ball(R2) - _lens(R1, R2, GAP)),
    ("intersection", _lens(R1, R2, GAP)),
    ("difference", _ball(R1) - _lens(R1, R2, GAP)),
])
def test_booleans_of_two_spheres_match_the_analytic_solids(two_spheres, operation, expected):
    grid, fa, fb = two_spheres
    field = combine([fa, fb], operation)
    mesh = mesh_field(field, grid)
    edges = edge_manifoldness(mesh.points, mesh.triangles)
    assert edges.boundary_edges == 0 and edges.nonmanifold_edges == 0
    assert orientation_outward(mesh.points, mesh.triangles).outward
    volume = enclosed_volume(mesh.points, mesh.triangles)
    assert abs(volume - expected) / expected < 0.01, f"{operation}: {volume:.1f} mm^3, analytic {expected:.1f}"
    # every vertex lies on the analytic boolean's boundary: within a tenth of a voxel away from the crease where
    # the two spheres meet, within half a voxel at it (marching cubes cuts sharp creases: the fields are not linear
    # across them)
    da = np.linalg.norm(mesh.points, axis=1) - R1
    db = np.linalg.norm(mesh.points - [GAP, 0, 0], axis=1) - R2
    analytic = {"union": np.minimum(da, db), "intersection": np.maximum(da, db),
                "difference": np.maximum(da, -db)}[operation]
    crease = np.abs(np.abs(da) - np.abs(db)) < 2 * 0.6
    assert np.abs(analytic[~crease]).max() < 0.1 * 0.6
    assert np.abs(analytic).max() < 0.5 * 0.6


def test_several_fields_fold_from_the_left(two_spheres):
    grid, fa, fb = two_spheres
    fc = np.roll(fb, 5, axis=0)
    assert np.array_equal(combine([fa, fb, fc], "difference"), np.maximum(np.maximum(fa, -fb), -fc))
    assert np.array_equal(combine([fa, fb, fc], "union"), np.minimum(np.minimum(fa, fb), fc))
    assert np.array_equal(combine([fa, fb, fc], "intersection"), np.maximum(np.maximum(fa, fb), fc))


def test_smooth_union_blends_only_near_the_crease(two_spheres):
    grid, fa, fb = two_spheres
    sharp = combine([fa, fb], "union")
    smooth = combine([fa, fb], "union", blend_mm=4.0)
    far = np.abs(fa - fb) >= 4.0
    assert np.array_equal(smooth[far], sharp[far])
    assert np.all(smooth <= sharp)
    assert (sharp - smooth).max() == pytest.approx(1.0, abs=0.05)  # k / 4 where the fields are equal
    v_sharp = enclosed_volume(*_arrays(mesh_field(sharp, grid)))
    v_smooth = enclosed_volume(*_arrays(mesh_field(smooth, grid)))
    assert v_smooth > v_sharp  # the blend fills the crease
    hard = combine([fa, fb], "difference", blend_mm=4.0)
    assert np.all(hard >= combine([fa, fb], "difference"))


def _arrays(mesh):
    return mesh.points, mesh.triangles


def test_torus_minus_sphere_is_closed_and_outward():
    t = torus(30.0, 10.0, around=256, across=128)
    s = sphere(14.0, around=128, across=64, centre=(30.0, 0.0, 0.0))
    grid = Grid.around((-40, 40, -40, 40, -10, 10), spacing=0.8, padding=4)
    ft = signed_distance(*t, grid, band_mm=3.0).values
    fs = signed_distance(*s, grid, band_mm=3.0).values
    mesh = mesh_field(combine([ft, fs], "difference"), grid)
    edges = edge_manifoldness(mesh.points, mesh.triangles)
    assert edges.boundary_edges == 0 and edges.nonmanifold_edges == 0
    assert orientation_outward(mesh.points, mesh.triangles).outward
    torus_volume = 2 * np.pi ** 2 * 30.0 * 10.0 ** 2
    assert 0.5 * torus_volume < enclosed_volume(mesh.points, mesh.triangles) < 0.95 * torus_volume


def test_offset_surfaces_grow_and_shrink(two_spheres):
    grid, fa, _ = two_spheres
    volumes = [enclosed_volume(*_arrays(mesh_field(fa, grid, offset_mm=o))) for o in (-2.0, 0.0, 2.0)]
    for offset, volume in zip((-2.0, 0.0, 2.0), volumes):
        assert volume == pytest.approx(_ball(R1 + offset), rel=0.01)


def test_rotated_grid_mesh_is_in_patient_space():
    from ._voxelise_shapes import rotation

    direction = rotation((1, 1, 0), 90.0)  # includes a handedness check: det > 0
    flip = direction @ np.diag([1.0, 1.0, -1.0])  # left-handed axes
    for d in (direction, flip):
        spacing = 0.7
        grid = Grid((60, 60, 60), (spacing,) * 3, tuple(-d @ np.full(3, 29.5 * spacing)), tuple(d.ravel()))
        points, triangles = sphere(15.0, around=128, across=64, centre=(1.0, 2.0, -1.0))
        mesh = mesh_field(signed_distance(points, triangles, grid, band_mm=2.0).values, grid)
        assert np.abs(np.linalg.norm(mesh.points - [1.0, 2.0, -1.0], axis=1) - 15.0).max() < 0.1 * spacing
        assert orientation_outward(mesh.points, mesh.triangles).outward


def test_isosurface_field_is_about_mm_and_negative_above_iso():
    k, j, i = np.mgrid[0:40, 0:40, 0:40].astype(np.float32)
    spacing = (0.5, 0.5, 0.5)
    r = np.sqrt((i - 20) ** 2 + (j - 20) ** 2 + (k - 20) ** 2) * 0.5
    intensity = 1000.0 - 100.0 * r  # 100 units per mm
    field = isosurface_field(intensity, 0.0 + 1000.0 - 500.0, spacing=spacing)  # the sphere r = 5 mm
    assert np.array_equal(field < 0, r < 5.0)
    near = np.abs(r - 5.0) < 2.0  # about mm near the surface (the scale is the gradient there)
    assert np.abs(field[near] - (r[near] - 5.0)).max() < 0.01
    with pytest.raises(ValueError, match="not inside"):
        isosurface_field(intensity, 5000.0, spacing=spacing)


def test_bad_inputs_are_refused(two_spheres):
    _, fa, fb = two_spheres
    with pytest.raises(ValueError, match="two or more"):
        combine([fa], "union")
    with pytest.raises(ValueError, match="resample"):
        combine([fa, fb[:-1]], "union")
    with pytest.raises(ValueError, match="operation"):
        combine([fa, fb], "xor")
    with pytest.raises(ValueError, match="blend"):
        combine([fa, fb], "union", blend_mm=-1)
    bad = fb.copy()
    bad[0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="infinite"):
        combine([fa, bad], "union")


def test_negated_padded_is_the_negated_field_with_a_closing_border():
    from algorithms.fields.csg import negated_padded

    rng = np.random.default_rng(3)
    for dtype in (np.float32, np.float64):
        field = rng.normal(0.0, 5.0, (7, 9, 11)).astype(dtype)
        for level in (0.0, 2.5, 100.0):
            as_float32 = field.astype(np.float32)
            expected = np.pad(np.negative(as_float32), 1,
                              constant_values=np.float32(-(max(float(np.max(as_float32)), level) + 1.0)))
            np.testing.assert_array_equal(negated_padded(field, level), expected)
    with pytest.raises(ValueError, match="3-D"):
        negated_padded(np.zeros((4, 4)))
