"""Visible voxel faces (source 000's baseline): exact geometry, orientation, VTK agreement, the coverage checker."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from algorithms.common.progress import OperationCancelled
from algorithms.common.validation import validated_solid
from algorithms.common.vtk_bridge import image_from_array, run_algorithm
from algorithms.compare.voxel_surfaces import (
    face_set,
    memory_usage,
    same_faces,
    strip_triangles,
    surface_face_set,
    voxel_face_keys,
)
from algorithms.datasets.volumes import FAMILIES, family
from algorithms.references.vtk_surfaces import vtk_voxel_surface
from algorithms.surfaces.voxel_faces import DIRECTION_NAMES, VoxelFacesFilter, voxel_faces

SPACING = (0.7, 1.1, 2.3)
ORIGIN = (-3.0, 5.0, 7.5)
COLIN_PATHS = (
    Path("/usr/share/mricron/templates/ch2.nii.gz"),  # Debian's mricron-data, installed by the set-up scripts
    Path(__file__).resolve().parents[4] / "shared" / "data" / "colin27_t1_ch2.nii.gz",
)


def signed_volume(points, triangles) -> float:
    """Volume enclosed by a closed triangle surface (positive when the triangles face outward)."""
    p = np.asarray(points, dtype=np.float64)[np.asarray(triangles)]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def triangle_normals(points, triangles) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)[np.asarray(triangles)]
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def colin27() -> np.ndarray:
    path = next((p for p in COLIN_PATHS if p.exists()), None)
    if path is None:
        pytest.skip("Colin 27 (colin27_t1_ch2.nii.gz) is not on this machine")
    from app.io import load_volume

    return load_volume(path).array


# --------------------------------------------------------------------------------------------------------------
# Exact geometry on analytic cases
# --------------------------------------------------------------------------------------------------------------
def test_single_voxel_faces_are_exact_and_outward():
    spacing, origin = (2.0, 3.0, 4.0), (1.0, 2.0, 3.0)
    faces = voxel_faces(np.ones((1, 1, 1), dtype=bool), spacing=spacing, origin=origin)
    assert faces.n_faces == 6 and faces.points.shape == (24, 3) and faces.triangles.shape == (12, 3)
    assert faces.points.dtype == np.float32
    assert faces.directions.tolist() == [0, 1, 2, 3, 4, 5]
    assert faces.voxel_ijk.tolist() == [[0, 0, 0]] * 6
    low, high = np.subtract(origin, np.divide(spacing, 2)), np.add(origin, np.divide(spacing, 2))
    corners = faces.points.reshape(6, 4, 3)
    for code, name in enumerate(DIRECTION_NAMES):
        axis = "xyz".index(name[1])
        plane = high[axis] if name[0] == "+" else low[axis]
        np.testing.assert_array_equal(corners[code, :, axis], plane)
        for other in {0, 1, 2} - {axis}:  # the four corners are the four combinations of the other two axes
            assert sorted(corners[code, :, other].tolist()) == sorted([low[other]] * 2 + [high[other]] * 2)
    normals = triangle_normals(faces.points, faces.triangles)
    expected = np.repeat(np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]]), 2, axis=0)
    np.testing.assert_array_equal(np.sign(normals), expected)
    assert signed_volume(faces.points, faces.triangles) == pytest.approx(24.0, rel=1e-12)


def test_box_has_the_analytic_face_count_area_and_volume():
    a, b, c = 3, 4, 5  # voxels along x, y, z
    model = np.zeros((9, 8, 7), dtype=bool)
    model[2 : 2 + c, 1 : 1 + b, 3 : 3 + a] = True
    faces = voxel_faces(model, spacing=SPACING, origin=ORIGIN)
    assert faces.n_faces == 2 * (a * b + b * c + c * a)
    sx, sy, sz = SPACING
    area = 0.5 * np.linalg.norm(triangle_normals(faces.points, faces.triangles), axis=1).sum()
    assert area == pytest.approx(2 * (a * sx * b * sy + b * sy * c * sz + c * sz * a * sx), rel=1e-6)
    assert signed_volume(faces.points, faces.triangles) == pytest.approx(a * b * c * sx * sy * sz, rel=1e-6)
    # The box's +x wall lies on the plane of voxel i = 5's far side.
    plus_x = faces.points.reshape(-1, 4, 3)[faces.directions == 1]
    np.testing.assert_allclose(plus_x[..., 0], ORIGIN[0] + SPACING[0] * 5.5, rtol=1e-6)


def test_faces_reach_the_volume_border():
    """Outside the volume counts as empty: a full volume shows exactly its six outer walls."""
    faces = voxel_faces(np.ones((2, 3, 4), dtype=bool))
    assert faces.n_faces == 2 * (4 * 3 + 3 * 2 + 2 * 4)
    assert np.bincount(faces.directions, minlength=6).tolist() == [6, 6, 8, 8, 12, 12]


def test_scalar_volume_is_solid_at_and_above_the_threshold():
    values = np.random.default_rng(3).integers(0, 10, size=(6, 7, 8)).astype(np.int16)
    by_value = voxel_faces(values, threshold=5, spacing=SPACING, origin=ORIGIN)
    by_mask = voxel_faces(values >= 5, spacing=SPACING, origin=ORIGIN)
    np.testing.assert_array_equal(by_value.points, by_mask.points)
    np.testing.assert_array_equal(by_value.voxel_ijk, by_mask.voxel_ijk)
    floats = voxel_faces(values.astype(np.float32), threshold=4.5)
    assert floats.n_faces == voxel_faces(values >= 5).n_faces


@pytest.mark.parametrize("seed", range(3))
def test_face_keys_from_geometry_match_the_faces_voxel_and_direction(seed):
    model = family("scatter-50", 9, seed=seed)
    faces = voxel_faces(model, spacing=SPACING, origin=ORIGIN)
    covered = surface_face_set(faces)
    assert covered.ok, covered.defects
    np.testing.assert_array_equal(covered.faces, voxel_face_keys(faces.voxel_ijk, faces.directions))
    # Every listed face is really a visible face of a solid voxel.
    i, j, k = faces.voxel_ijk.T
    assert model[k, j, i].all()


# --------------------------------------------------------------------------------------------------------------
# Orientation: per connected component, the enclosed volume is that of its voxels
# --------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["scatter-20", "spheres", "pillars-50"])
def test_each_component_encloses_its_own_voxel_volume(name):
    model = family(name, 14, seed=4)
    labels, count = ndimage.label(model)  # 6-connected: faces never separate two voxels of one component
    faces = voxel_faces(model, spacing=SPACING, origin=ORIGIN)
    i, j, k = faces.voxel_ijk.T
    face_label = labels[k, j, i]
    voxel_volume = np.prod(SPACING)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    triangles = faces.triangles.reshape(-1, 2, 3)
    for label in range(1, count + 1):
        own = triangles[face_label == label].reshape(-1, 3)
        assert signed_volume(faces.points, own) == pytest.approx(sizes[label] * voxel_volume, rel=1e-5)


def test_cavity_faces_point_into_the_cavity():
    shell = np.ones((5, 5, 5), dtype=bool)
    shell[2, 2, 2] = False
    faces = voxel_faces(shell)
    assert faces.n_faces == 6 * 25 + 6
    assert signed_volume(faces.points, faces.triangles) == pytest.approx(124.0)
    inner = np.all(faces.voxel_ijk == [[2, 2, 1]], axis=1)  # the voxel below the cavity: its +z face is inside
    assert faces.directions[inner].tolist() == [5]


# --------------------------------------------------------------------------------------------------------------
# Agreement with VTK's vtkThreshold + vtkDataSetSurfaceFilter
# --------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", FAMILIES)
@pytest.mark.parametrize("seed", range(3))
def test_face_set_equals_vtk_threshold_surface(name, seed):
    model = family(name, 12, seed=seed)
    faces = voxel_faces(model, spacing=SPACING, origin=ORIGIN)
    points, quads = vtk_voxel_surface(model, None, SPACING, ORIGIN)
    assert len(faces.triangles) == 2 * len(quads)
    equal, report = same_faces(faces, face_set(points, quads=quads, spacing=SPACING, origin=ORIGIN))
    assert equal, report


def test_ct_phantom_bone_equals_vtk(ct_phantom):
    volume = ct_phantom
    faces = voxel_faces(volume.array, threshold=300.0, spacing=volume.spacing, origin=volume.origin)
    assert faces.n_faces > 1000
    points, quads = vtk_voxel_surface(volume.array, 300.0, volume.spacing, volume.origin)
    assert len(faces.triangles) == 2 * len(quads)
    vtk_faces = face_set(points, quads=quads, spacing=volume.spacing, origin=volume.origin)
    equal, report = same_faces(faces, vtk_faces)
    assert equal, report


def test_colin27_crop_equals_vtk():
    crop = colin27()[60:108, 80:136, 66:114]  # 48 x 56 x 48 voxels through the brain, 1 mm
    faces = voxel_faces(crop, threshold=70, origin=(66.0, 80.0, 60.0))
    assert faces.n_faces > 10_000
    points, quads = vtk_voxel_surface(crop, 70, (1.0, 1.0, 1.0), (66.0, 80.0, 60.0))
    assert len(faces.triangles) == 2 * len(quads)
    equal, report = same_faces(faces, face_set(points, quads=quads, origin=(66.0, 80.0, 60.0)))
    assert equal, report


# --------------------------------------------------------------------------------------------------------------
# The VTK filter
# --------------------------------------------------------------------------------------------------------------
def test_filter_honours_spacing_origin_and_threshold(ct_phantom):
    volume = ct_phantom
    vtk_filter = VoxelFacesFilter()
    vtk_filter.SetInputDataObject(0, image_from_array(volume.array, volume.spacing, volume.origin))
    vtk_filter.SetThreshold(300.0)
    polydata = run_algorithm(vtk_filter)
    core = voxel_faces(volume.array, threshold=300.0, spacing=volume.spacing, origin=volume.origin)
    assert polydata.GetNumberOfPolys() == len(core.triangles)
    equal, report = same_faces(core, surface_face_set(polydata, spacing=volume.spacing, origin=volume.origin))
    assert equal, report


def test_filter_setter_marks_modified_only_on_change():
    vtk_filter = VoxelFacesFilter()
    assert vtk_filter.GetThreshold() == 0.5
    before = vtk_filter.GetMTime()
    vtk_filter.SetThreshold(0.5)
    assert vtk_filter.GetMTime() == before
    vtk_filter.SetThreshold(2.0)
    assert vtk_filter.GetMTime() > before and vtk_filter.GetThreshold() == 2.0


def test_progress_is_reported_and_cancellation_propagates():
    model = family("spheres", 16)
    seen = []
    voxel_faces(model, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) >= 6

    def cancel(fraction):
        raise OperationCancelled("stop")

    with pytest.raises(OperationCancelled):
        voxel_faces(model, progress=cancel)


# --------------------------------------------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("volume", "options", "message"),
    [
        (np.ones((3, 3), dtype=bool), {}, "expected a 3D volume"),
        (np.ones((0, 3, 3), dtype=bool), {}, "the volume is empty"),
        (np.ones((2, 2, 2), dtype=complex), {"threshold": 1}, "boolean mask or a real-valued volume"),
        (np.ones((2, 2, 2)), {}, "needs a threshold"),
        (np.ones((2, 2, 2), dtype=bool), {"threshold": 1}, "already solid/empty"),
        (np.ones((2, 2, 2)), {"threshold": np.nan}, "threshold must be finite"),
        (np.ones((2, 2, 2)), {"threshold": "high"}, "threshold must be a number"),
        (np.ones((2, 2, 2), dtype=bool), {"spacing": (1.0, 0.0, 1.0)}, "spacing must be three positive"),
        (np.ones((2, 2, 2), dtype=bool), {"spacing": (1.0, 1.0)}, "spacing must be three positive"),
        (np.ones((2, 2, 2), dtype=bool), {"origin": (0.0, np.inf, 0.0)}, "origin must be three finite"),
        (np.ones((2, 2, 2), dtype=bool), {"origin": None}, "spacing and origin must be three numbers"),
    ],
)
def test_invalid_input_raises(volume, options, message):
    with pytest.raises(ValueError, match=message):
        voxel_faces(volume, **options)


def test_surface_helpers_reject_what_they_cannot_handle():
    faces = voxel_faces(np.ones((1, 1, 1), dtype=bool))
    with pytest.raises(ValueError, match="carries its own spacing and origin"):
        surface_face_set(faces, spacing=(2.0, 2.0, 2.0))
    with pytest.raises(ValueError, match="cannot take the face set of a ndarray"):
        surface_face_set(faces.points)
    with pytest.raises(ValueError, match="no memory accounting for a ndarray"):
        memory_usage(faces.points)


def test_vtk_reference_validates_like_the_core():
    with pytest.raises(ValueError, match="needs a threshold"):
        vtk_voxel_surface(np.ones((2, 2, 2)))
    assert validated_solid(np.ones((1, 1, 1), dtype=bool))[1] is None


# --------------------------------------------------------------------------------------------------------------
# The coverage checker finds every kind of defect
# --------------------------------------------------------------------------------------------------------------
@pytest.fixture
def cube_faces():
    return voxel_faces(family("spheres", 10, seed=1), spacing=SPACING, origin=ORIGIN)


def _check(points, triangles=None, **options):
    return face_set(points, triangles, spacing=SPACING, origin=ORIGIN, **options)


def test_checker_accepts_either_diagonal_but_not_a_flipped_face(cube_faces):
    quads = cube_faces.triangles.reshape(-1, 2, 3)[:, 0, :].copy()  # (4f, 4f+1, 4f+2)
    quads = np.column_stack([quads, quads[:, 0] + 3])
    other_diagonal = quads[:, [[0, 1, 3], [1, 2, 3]]].reshape(-1, 3)
    equal, report = same_faces(cube_faces, _check(cube_faces.points, other_diagonal))
    assert equal, report
    flipped = cube_faces.triangles.copy()
    flipped[:2] = flipped[:2, [1, 0, 2]]  # both triangles of face 0 reversed: a clean face, facing inward
    result = _check(cube_faces.points, flipped)
    assert result.ok
    equal, report = same_faces(cube_faces, result)
    assert not equal and "1 faces only in the first" in report and "1 faces only in the second" in report


@pytest.mark.parametrize(
    ("corrupt", "defect"),
    [
        (lambda t: np.concatenate([t, t[:1]]), "overdrawn faces"),
        (lambda t: t[1:], "half-covered faces"),
        (lambda t: np.concatenate([t[:1, [1, 0, 2]], t[1:]]), "faces with mixed winding"),
        (lambda t: np.concatenate([t[:1], t[:1, [1, 2, 0]], t[2:]]), "faces with overlapping halves"),
        (lambda t: np.concatenate([t, [[t[0, 0], t[0, 0], t[0, 1]]]]), "degenerate triangles"),
    ],
)
def test_checker_counts_each_defect(cube_faces, corrupt, defect):
    result = _check(cube_faces.points, corrupt(cube_faces.triangles))
    assert not result.ok
    assert result.defects[defect] >= 1
    assert same_faces(cube_faces, result)[0] is False


def test_checker_rejects_points_off_the_lattice(cube_faces):
    moved = cube_faces.points.copy()
    moved[0, 0] += 0.3 * SPACING[0]
    result = _check(moved, cube_faces.triangles)
    assert result.defects["off-grid triangles"] == 2  # both triangles of face 0 use corner 0


def test_checker_counts_zero_area_triangles_as_degenerate():
    collinear = np.array([[0, 0, 0], [1, 1, 0], [2, 2, 0]]) - 0.5
    assert face_set(collinear, np.array([[0, 1, 2]])).defects["degenerate triangles"] == 1


def test_checker_rejects_triangles_larger_than_a_face():
    corners = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0]]) - 0.5  # on the lattice, but two voxels wide
    result = face_set(corners, np.array([[0, 1, 2]]))
    assert result.defects["off-grid triangles"] == 1 and len(result) == 0


def test_checker_reports_degenerate_strip_triangles():
    points = np.array([[-0.5, -0.5, 0.5], [-0.5, 0.5, 0.5], [0.5, -0.5, 0.5], [0.5, 0.5, 0.5]])
    clean = face_set(points, strips=(np.array([0, 4]), np.array([1, 0, 3, 2])))
    assert clean.ok and len(clean) == 1  # the +z face of voxel (0, 0, 0)
    assert clean.faces.tolist() == [[0, 0, 1, 2, 1]]
    # A repeated vertex, the classic way to join strips, draws zero-area triangles: they must be reported.
    joined = face_set(points, strips=(np.array([0, 6]), np.array([1, 0, 3, 2, 2, 2])))
    assert joined.defects["degenerate triangles"] == 2 and not joined.ok


def test_strip_triangles_alternate_winding():
    triangles = strip_triangles(np.array([0, 5, 8]), np.array([0, 1, 2, 3, 4, 10, 11, 12]))
    assert triangles.tolist() == [[0, 1, 2], [2, 1, 3], [2, 3, 4], [10, 11, 12]]


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"points": np.zeros((4, 2))}, "points must be an"),
        ({"points": np.zeros((4, 3)), "triangles": np.array([[0, 1, 4]])}, "point ids must lie in"),
        ({"points": np.zeros((4, 3)), "triangles": np.array([[0, 1, 2, 3]])}, "triangles must be an integer"),
        ({"points": np.zeros((4, 3)), "quads": np.array([[0.0, 1.0, 2.0, 3.0]])}, "quads must be an integer"),
    ],
)
def test_checker_invalid_input_raises(arguments, message):
    with pytest.raises(ValueError, match=message):
        face_set(**arguments)
