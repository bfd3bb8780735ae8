"""Isosurface stuffing: the angle guarantee, conformity, volume, boundary fidelity and bad inputs.

Every mesh here is checked against the paper's bounds (10.7-164.8 degrees, or 8.9-158.8 with the other alpha pair):
analytic solids, random smooth fields and the sample CT's skull. A planted bad stencil entry must make the checks
fail.
"""

from __future__ import annotations

import numpy as np
import pytest

from algorithms.compare.measures import enclosed_volume
from algorithms.compare.tet_quality import boundary_fidelity, check_dihedral_bounds, conformity
from algorithms.meshing.isosurface_stuffing import ANGLE_BOUNDS, isosurface_stuffing, stencils, stuffing_table


def _grid(n, spacing=1.0):
    axis = (np.arange(n, dtype=np.float64) - (n - 1) / 2.0) * spacing
    return np.meshgrid(axis, axis, axis, indexing="ij")  # z, y, x


def sphere(n=48, r=16.0):
    z, y, x = _grid(n)
    return (r - np.sqrt(x * x + y * y + z * z)).astype(np.float32)


def torus(n=56, big=16.0, small=6.0):
    z, y, x = _grid(n)
    ring = np.sqrt(x * x + y * y) - big
    return (small - np.sqrt(ring * ring + z * z)).astype(np.float32)


def thin_plate(n=48, thickness=2.5, tilt=0.3):
    z, y, x = _grid(n)
    distance = np.abs(z - tilt * x) / np.sqrt(1 + tilt * tilt)
    return np.minimum(thickness / 2 - distance, 18.0 - np.maximum(np.abs(x), np.abs(y))).astype(np.float32)


def touching_balls(n=48, r=10.0):
    z, y, x = _grid(n)
    a = r - np.sqrt((x - r) ** 2 + y * y + z * z)
    b = r - np.sqrt((x + r) ** 2 + y * y + z * z)
    return np.maximum(a, b).astype(np.float32)


def smooth_random(seed, n=40):
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    field = gaussian_filter(rng.standard_normal((n, n, n)), 3.0)
    return (field / field.std()).astype(np.float32)


SOLIDS = {"sphere": sphere, "torus": torus, "thin plate": thin_plate, "touching balls": touching_balls}
CENTRED = {"origin": (-23.5, -23.5, -23.5)}


def _origin(field):
    return tuple(-(n - 1) / 2.0 for n in field.shape[::-1])


def _assert_guarantee(result, alpha):
    low, high = ANGLE_BOUNDS[alpha]
    bad = check_dihedral_bounds(result.mesh.points, result.mesh.tetrahedra, low, high)
    assert bad.size == 0, f"{bad.size} tetrahedra outside [{low}, {high}] degrees"
    assert result.mesh.n_tetrahedra > 0


@pytest.mark.parametrize("alpha", ["10.7", "8.9"])
@pytest.mark.parametrize("name", list(SOLIDS))
@pytest.mark.parametrize("h", [1.0, 1.7])
def test_analytic_solids_keep_the_angle_bounds_and_conform(name, h, alpha):
    field = SOLIDS[name]()
    result = isosurface_stuffing(field, 0.0, h=h, origin=_origin(field), alpha=alpha)
    _assert_guarantee(result, alpha)
    report = conformity(result.mesh.points, result.mesh.tetrahedra, on_surface=result.on_surface)
    assert report["overshared_faces"] == 0 and report["nonpositive_tetrahedra"] == 0
    assert report["boundary_faces"] == len(result.boundary) and report["boundary_faces_off_surface"] == 0
    assert report["boundary_closed"] and report["boundary_outward"] and report["conforming"], report


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("alpha", ["10.7", "8.9"])
def test_random_smooth_fields_keep_the_angle_bounds(seed, alpha):
    field = smooth_random(seed)
    for iso in (-0.5, 0.0, 0.7):
        result = isosurface_stuffing(field, iso, h=1.3, alpha=alpha, spacing=(1.0, 1.1, 0.9))
        _assert_guarantee(result, alpha)
        report = conformity(result.mesh.points, result.mesh.tetrahedra, on_surface=result.on_surface)
        assert report["conforming"], report


@pytest.mark.parametrize("h", [3.0, 2.0, 1.5])
def test_the_sample_ct_skull_keeps_the_angle_bounds_at_three_lattice_sizes(h):
    from app.datasets import ct_head_phantom

    volume = ct_head_phantom((88, 256, 256))  # the sample's field of view at 1.1 x 1.1 x 3 mm
    result = isosurface_stuffing(volume.array, 300.0, h=h, spacing=volume.spacing, origin=volume.origin)
    _assert_guarantee(result, "10.7")
    assert result.stats["bytes_per_lattice_point"] < 44


def _planted(modify):
    counts, faces, n_faces, tets = (a.copy() for a in stuffing_table())
    modify(counts, faces, n_faces, tets)
    return counts, faces, n_faces, tets


def test_a_planted_bad_stencil_entry_fails_the_angle_check():
    field = sphere()

    def flip(counts, faces, n_faces, tets):  # the one-tetrahedron stencil at a lone positive vertex, inside out
        for signs in ("+---", "-+--", "--+-", "---+"):
            index = stencils.pattern_index(signs)
            tets[index, :, 0, [0, 1]] = tets[index, :, 0, [1, 0]]

    good = isosurface_stuffing(field, 0.0, h=1.7, origin=_origin(field))
    bad = isosurface_stuffing(field, 0.0, h=1.7, origin=_origin(field), table=_planted(flip))
    assert check_dihedral_bounds(good.mesh.points, good.mesh.tetrahedra, *ANGLE_BOUNDS["10.7"]).size == 0
    assert check_dihedral_bounds(bad.mesh.points, bad.mesh.tetrahedra, *ANGLE_BOUNDS["10.7"]).size > 0


def test_a_planted_wrong_parity_choice_breaks_conformity():
    field = torus()

    def swap(counts, faces, n_faces, tets):  # ++-0 pyramids: the other diagonal than the parity rule's
        for signs in ("++-0", "++0-", "-0++", "0-++"):
            index = stencils.pattern_index(signs)
            tets[index, [0, 1]] = tets[index, [1, 0]]

    good = isosurface_stuffing(field, 0.0, h=1.3, origin=_origin(field))
    bad = isosurface_stuffing(field, 0.0, h=1.3, origin=_origin(field), table=_planted(swap))
    assert conformity(good.mesh.points, good.mesh.tetrahedra, on_surface=good.on_surface)["conforming"]
    report = conformity(bad.mesh.points, bad.mesh.tetrahedra, on_surface=bad.on_surface)
    assert report["boundary_faces_off_surface"] > 0 and not report["conforming"]


@pytest.mark.parametrize("name", ["sphere", "torus"])
def test_volume_within_one_percent_of_marching_cubes_at_one_voxel(name):
    from algorithms.surfaces.marching_cubes import marching_cubes

    field = SOLIDS[name]()
    result = isosurface_stuffing(field, 0.0, h=1.0, origin=_origin(field))
    surface = marching_cubes(field, 0.0, origin=_origin(field))
    reference = enclosed_volume(surface)
    assert result.mesh.volumes().sum() == pytest.approx(reference, rel=0.01)
    fidelity = boundary_fidelity(surface.points, result.mesh.points, result.boundary, within=(0.5, 1.0))
    assert fidelity["within_mm"]["1"] >= 0.95


def test_volume_of_the_small_ct_within_one_percent_at_one_voxel():
    """The egg phantom's skull (2 to 9 mm of bone) at h = one voxel; the FORBILD head's 6 mm shell and sub-voxel
    bone plates, on 4 mm slices, are thinner than this claim is about (1.4 % there)."""
    from algorithms.surfaces.marching_cubes import marching_cubes
    from app.datasets import egg_head_phantom

    volume = egg_head_phantom(shape=(54, 128, 128), spacing=(1.875, 1.875, 4.0))
    padded = np.pad(volume.array, 1, constant_values=volume.array.min())
    origin = np.asarray(volume.origin) - np.asarray(volume.spacing)
    result = isosurface_stuffing(padded, 300.0, h=1.875, spacing=volume.spacing, origin=origin)
    surface = marching_cubes(padded, 300.0, spacing=volume.spacing, origin=origin)
    assert result.mesh.volumes().sum() == pytest.approx(enclosed_volume(surface), rel=0.01)
    report = conformity(result.mesh.points, result.mesh.tetrahedra, on_surface=result.on_surface)
    assert report["conforming"], report


@pytest.mark.parametrize("cut, tolerance", [("bisection", 0.025), ("linear", 0.035)])
def test_a_distance_field_negative_inside(cut, tolerance):
    field = -sphere(r=12.0)  # a signed distance sampled on a 1 mm grid, negative inside
    result = isosurface_stuffing(field, 0.0, h=1.5, origin=_origin(field), inside="below", cut=cut)
    _assert_guarantee(result, "10.7")
    radii = np.linalg.norm(result.mesh.points[np.unique(result.boundary)], axis=1)
    # Boundary points lie on the zero set of the trilinear interpolant (within about 1/8 voxel^2 x curvature of
    # the sphere, 0.01 mm at r = 12 mm, plus 1/1000 h of bisection); linear cuts add the chord's sagitta along an
    # edge, up to h^2 / (8 r) = 0.023 mm.
    assert np.abs(radii - 12.0).max() < tolerance
    assert result.mesh.volumes().sum() == pytest.approx(4 / 3 * np.pi * 12.0 ** 3, rel=0.01)


@pytest.mark.parametrize("kwargs, message", [
    ({"iso": 50.0}, "outside the values"),
    ({"h": 0.0}, "positive number of mm"),
    ({"h": 500.0}, "larger than the volume"),
    ({"alpha": "12"}, "alpha must name"),
    ({"inside": "left"}, "inside must be"),
    ({"cut": "newton"}, "cut must be"),
    ({"h": 0.05, "memory_limit": 2**30}, "GiB"),
])
def test_bad_inputs_are_refused_with_a_clear_message(kwargs, message):
    arguments = {"iso": 0.0, "h": 2.0, **kwargs}
    with pytest.raises(ValueError, match=message):
        isosurface_stuffing(sphere(), arguments.pop("iso"), **arguments)


def test_empty_fields_are_refused():
    with pytest.raises(ValueError, match="empty"):  # an empty mask: zero everywhere
        isosurface_stuffing(np.zeros((8, 8, 8)), 0.5, h=1.0)
    distance = np.full((8, 8, 8), 5.0, dtype=np.float32)
    distance[0, 0, 0] = 7.0
    with pytest.raises(ValueError, match="outside the values"):  # a distance field with nothing inside
        isosurface_stuffing(distance, 0.0, h=1.0, inside="below")
