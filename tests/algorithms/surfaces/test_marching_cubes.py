"""Marching cubes with Bourke's tables: the tables, case by case and mesh by mesh against vtkMarchingCubes,
analytic areas and volumes, topology, normals, preview, several isovalues, the VTK filter and every ValueError.

How the comparison with vtkMarchingCubes is made exact
------------------------------------------------------
:func:`test_case_by_case_against_vtk` runs both on a single cell for each of the 254 non-empty cases. The
triangulations are identical (same triangles, same winding) except in the 120 cases listed in
``AMBIGUOUS_FACE_CASES``: exactly the cases in which some face of the cell has two diagonally opposite corners
inside and the other two outside. There Bourke's table joins the inside corners across the face and VTK's
separates them, and our triangles are VTK's for the complementary case with reversed winding.

On whole volumes (``test_matches_vtk_except_on_ambiguous_cells_*``) the triangles are compared after leaving
out, on both sides, every triangle whose centroid lies in the closed box of a cell whose case is in that list.
The rule depends only on the triangle and the volume, so a triangle present in both meshes is kept or dropped in
both; everything kept must match one to one, coordinates within 1e-5 of the mesh size. The vertex sets (one vertex
per cut edge, merged where the isovalue equals a sample) must be equal without exception. Where ambiguous cells
occur the surfaces' area and enclosed volume are compared within 0.1 % instead (on the CT phantom with noise;
the clean phantom has none at the isovalues tested, so there every triangle is compared); on random fields,
where they are frequent, the complement identity ours(v, T) = reversed VTK(-v, -T)
(:func:`test_complement_identity_on_random_fields`) covers those cells exactly.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.special import ellipeinc, ellipkinc
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonMisc import vtkContourValues
from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D, vtkMarchingCubes

from algorithms import compare as sc
from algorithms.common.progress import OperationCancelled
from algorithms.common.vtk_bridge import VTKError, image_from_array, polydata_arrays, run_algorithm
from algorithms.datasets.volumes import ellipsoid_field, sphere_field, torus_field
from algorithms.surfaces.marching_cubes import MarchingCubesFilter, MarchingCubesMesh, marching_cubes
from algorithms.surfaces.marching_cubes import core, count_triangles, kernels, tables

# VTK case numbers (bit c set when corner c is inside, value >= iso) whose cell has an ambiguous face. The set is
# closed under complement, so Bourke's numbering (bits of the corners below the isovalue) gives the same list.
AMBIGUOUS_FACE_CASES = (
    5, 10, 18, 21, 22, 24, 26, 28, 30, 33, 36, 37, 41, 42, 44, 45, 52, 53, 56, 58, 60, 61, 62, 66, 67, 69, 72,
    73, 74, 75, 80, 81, 82, 83, 84, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95, 97, 101, 104, 105, 106, 107, 109,
    117, 120, 121, 122, 123, 124, 126, 129, 131, 132, 133, 134, 135, 138, 146, 148, 149, 150, 151, 154, 158, 160,
    161, 162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 180, 181, 182, 183, 186, 188, 189,
    193, 194, 195, 197, 199, 202, 203, 210, 211, 213, 214, 218, 219, 222, 225, 227, 229, 231, 233, 234, 237, 245,
    250,
)
FACES = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (3, 2, 6, 7), (0, 3, 7, 4), (1, 2, 6, 5))
RTOL = 1e-5


# --------------------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------------------
def vtk_contour(volume, levels, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), *, normals=False,
                algorithm=vtkMarchingCubes):
    contour = algorithm()
    contour.SetInputData(image_from_array(volume, spacing, origin))
    for index, level in enumerate(np.atleast_1d(levels)):
        contour.SetValue(index, float(level))
    contour.SetComputeNormals(normals)
    return run_algorithm(contour)


def cell_cases(volume, iso) -> np.ndarray:
    """VTK case of every cell, shape (nz-1, ny-1, nx-1)."""
    inside = (np.asarray(volume) >= iso).astype(np.int64)
    nz, ny, nx = inside.shape
    cases = np.zeros((nz - 1, ny - 1, nx - 1), dtype=np.int64)
    for corner, (di, dj, dk) in enumerate(tables.CORNER_OFFSETS):
        cases |= inside[dk:nz - 1 + dk, dj:ny - 1 + dj, di:nx - 1 + di] << corner
    return cases


def off_ambiguous_cells(points, triangles, ambiguous, spacing, origin) -> np.ndarray:
    """True for triangles whose centroid touches no ambiguous cell (closed boxes; both floor and ceil on ties)."""
    centroid = (points[triangles].astype(np.float64).mean(axis=1) - np.asarray(origin)) / np.asarray(spacing)
    limits = np.array(ambiguous.shape[::-1]) - 1  # largest cell index along i, j, k
    candidates = [np.clip(np.floor(centroid + shift).astype(np.int64), 0, limits) for shift in (-1e-6, 1e-6)]
    touches = np.zeros(len(triangles), dtype=bool)
    for ci in (candidates[0][:, 0], candidates[1][:, 0]):
        for cj in (candidates[0][:, 1], candidates[1][:, 1]):
            for ck in (candidates[0][:, 2], candidates[1][:, 2]):
                touches |= ambiguous[ck, cj, ci]
    return ~touches


def assert_same_points(points_a, points_b, rtol=RTOL):
    assert len(points_a) == len(points_b)
    diagonal = np.linalg.norm(np.ptp(np.concatenate([points_a, points_b]), axis=0))
    assert cKDTree(points_b).query(points_a)[0].max() <= rtol * diagonal
    assert cKDTree(points_a).query(points_b)[0].max() <= rtol * diagonal


def single_cell(inside_bits: int) -> np.ndarray:
    """A 2x2x2 volume with value 1 at the corners in ``inside_bits`` (VTK case numbering), 0 elsewhere."""
    cell = np.zeros((2, 2, 2), dtype=np.float32)
    for corner, (di, dj, dk) in enumerate(tables.CORNER_OFFSETS):
        cell[dk, dj, di] = (inside_bits >> corner) & 1
    return cell


def ellipsoid_area(a, b, c) -> float:
    """Exact area of an ellipsoid with semi-axes a > b > c (Legendre's elliptic-integral form)."""
    a, b, c = sorted((a, b, c), reverse=True)
    phi = np.arccos(c / a)
    m = (a * a * (b * b - c * c)) / (b * b * (a * a - c * c))
    return 2 * np.pi * c * c + 2 * np.pi * a * b / np.sin(phi) * (
        ellipeinc(phi, m) * np.sin(phi) ** 2 + ellipkinc(phi, m) * np.cos(phi) ** 2
    )


def closed_random_field(rng, shape=(14, 15, 16)) -> np.ndarray:
    """Random integers 0..999 (int16) with a border of zeros, so every surface at iso > 0 is closed."""
    field = rng.integers(0, 1000, size=shape).astype(np.int16)
    field[[0, -1]] = 0
    field[:, [0, -1]] = 0
    field[:, :, [0, -1]] = 0
    return field


# --------------------------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------------------------
def test_edge_table_lists_exactly_the_cut_edges():
    for case in range(256):
        below = [(case >> corner) & 1 for corner in range(8)]
        cut = sum(1 << edge for edge, (a, b) in enumerate(tables.EDGE_CORNERS) if below[a] != below[b])
        assert tables.EDGE_TABLE[case] == cut, case
        row = tables.TRIANGLE_TABLE[case]
        used = set(row[row >= 0].tolist())
        assert sum(1 << edge for edge in used) == cut, case
        assert np.all(row[len(row[row >= 0]):] == -1) and len(row[row >= 0]) % 3 == 0, case


def test_each_case_is_a_patch_closed_inside_the_cell():
    """A triangle side between edges on one face of the cube lies on that face and is used once; any other side
    crosses the cell's interior and is shared by exactly two triangles of the case."""
    def faces_of(edge):
        corners = set(tables.EDGE_CORNERS[edge].tolist())
        return {f for f in range(6) if corners <= set(FACES[f])}

    for case in range(256):
        row = tables.TRIANGLE_TABLE[case]
        triangles = row[row >= 0].reshape(-1, 3)
        sides: dict[frozenset, int] = {}
        for triangle in triangles:
            for a, b in ((0, 1), (1, 2), (2, 0)):
                key = frozenset((int(triangle[a]), int(triangle[b])))
                sides[key] = sides.get(key, 0) + 1
        for side, count in sides.items():
            a, b = tuple(side)
            assert count == (1 if faces_of(a) & faces_of(b) else 2), (case, side)


def test_ambiguous_face_cases_are_the_ones_listed():
    def has_ambiguous_face(case):
        for face in FACES:
            bits = [(case >> corner) & 1 for corner in face]
            if bits[0] == bits[2] and bits[1] == bits[3] and bits[0] != bits[1]:
                return True
        return False

    assert tuple(c for c in range(256) if has_ambiguous_face(c)) == AMBIGUOUS_FACE_CASES


# --------------------------------------------------------------------------------------------------------------
# Against vtkMarchingCubes
# --------------------------------------------------------------------------------------------------------------
def test_case_by_case_against_vtk():
    identical, complement_reversed = [], []
    for case in range(1, 255):
        ours = marching_cubes(single_cell(case), 0.5)
        theirs = polydata_arrays(vtk_contour(single_cell(case), 0.5))
        if sc.same_triangles(ours.points, ours.triangles, *theirs).equal:
            identical.append(case)
        complement = polydata_arrays(vtk_contour(1.0 - single_cell(case), 0.5))
        reversed_complement = complement[1][:, ::-1]
        if sc.same_triangles(ours.points, ours.triangles, complement[0], reversed_complement).equal:
            complement_reversed.append(case)
    assert sorted(set(range(1, 255)) - set(identical)) == list(AMBIGUOUS_FACE_CASES)
    assert complement_reversed == list(range(1, 255))


@pytest.fixture(scope="module")
def ct_small():
    """The CT phantom's whole field of view on a coarse grid (2.9 x 2.9 x 6.6 mm): the skull is a closed surface."""
    from app.datasets import ct_head_phantom

    return ct_head_phantom(shape=(40, 96, 96))


def _compare_with_vtk(volume, iso, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    ours = marching_cubes(volume, iso, spacing=spacing, origin=origin)
    points, triangles = polydata_arrays(vtk_contour(volume, iso, spacing, origin))
    assert_same_points(ours.points, points)
    ambiguous = np.isin(cell_cases(volume, iso), AMBIGUOUS_FACE_CASES)
    keep_ours = off_ambiguous_cells(ours.points, ours.triangles, ambiguous, spacing, origin)
    keep_theirs = off_ambiguous_cells(points, triangles, ambiguous, spacing, origin)
    comparison = sc.same_triangles(ours.points, ours.triangles[keep_ours], points, triangles[keep_theirs], rtol=RTOL)
    assert comparison.equal, comparison.summary()
    return ours, (points, triangles), keep_ours, keep_theirs, int(ambiguous.sum())


@pytest.mark.parametrize("noise_hu", [0.0, 30.0])
@pytest.mark.parametrize("iso", [300.0, 300.5, -300.0])
def test_matches_vtk_except_on_ambiguous_cells_ct(iso, noise_hu):
    """Bone (300 HU, with samples exactly at the isovalue, and 300.5 HU) and skin (-300 HU) of the CT phantom, clean
    and with 30 HU of noise. The phantom's thin bone, air cells and resolution rods make some cells ambiguous (where
    Bourke's and VTK's tables split a cell differently); every other triangle is the same, and the area and enclosed
    volume differ by no more than the ambiguous cells can hold."""
    from app.datasets import ct_head_phantom

    volume = ct_head_phantom(shape=(40, 96, 96), spacing=(2.5, 2.5, 5.4), noise_hu=noise_hu, seed=1)
    ours, theirs, kept, kept_theirs, ambiguous = _compare_with_vtk(volume.array, iso, volume.spacing, volume.origin)
    assert kept.mean() > 0.99
    in_ambiguous = max(sc.surface_area(ours.points, ours.triangles[~kept]),
                       sc.surface_area(theirs[0], theirs[1][~kept_theirs]))
    area, volume_mm3 = sc.surface_area(ours), sc.enclosed_volume(ours)
    rounding = 1e-7  # float32 vertices: relative rounding of sums over 10^5 triangles
    assert abs(area - sc.surface_area(theirs)) <= in_ambiguous + rounding * area
    assert abs(volume_mm3 - sc.enclosed_volume(theirs)) <= ambiguous * np.prod(volume.spacing) + rounding * volume_mm3


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("iso", [500.0, 500.5])
def test_matches_vtk_except_on_ambiguous_cells_random(seed, iso):
    """Random integer fields: at 500 many samples equal the isovalue (vertices merged onto samples)."""
    field = np.random.default_rng(seed).integers(0, 1000, size=(12, 13, 14)).astype(np.int16)
    _, _, kept, _, _ = _compare_with_vtk(field, iso, spacing=(0.7, 1.1, 1.9), origin=(-3.0, 2.0, 5.0))
    assert kept.mean() > 0.2  # the comparison still covers a good part of the mesh


def test_matches_vtk_on_a_binary_mask():
    """Isovalue 1 on a 0/1 mask puts every vertex on a sample: heavy merging and dropped collapsed triangles."""
    mask = (np.random.default_rng(7).random((10, 11, 12)) < 0.4).astype(np.uint8)
    ours, _, _, _, _ = _compare_with_vtk(mask, 1.0)
    assert len(np.unique(ours.points, axis=0)) == len(ours.points)
    t = ours.triangles
    assert np.all((t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2]))
    _compare_with_vtk(mask, 0.5)


@pytest.mark.parametrize("seed", [3, 4])
def test_complement_identity_on_random_fields(seed):
    """Without samples equal to the isovalue, ours(v, T) is VTK's surface of (-v, -T) with reversed winding,
    including every ambiguous cell."""
    field = np.random.default_rng(seed).integers(0, 1000, size=(12, 13, 14)).astype(np.int16)
    ours = marching_cubes(field, 500.5)
    points, triangles = polydata_arrays(vtk_contour(-field, -500.5))
    comparison = sc.same_triangles(ours.points, ours.triangles, points, triangles[:, ::-1])
    assert comparison.equal, comparison.summary()


def test_ct_phantom_at_a_scanner_size_matches_vtk():
    from app.datasets import ct_head_phantom

    volume = ct_head_phantom((88, 256, 256))  # the sample's field of view at 1.1 x 1.1 x 3 mm
    ours, theirs, kept, _, _ = _compare_with_vtk(volume.array, 300.0, volume.spacing, volume.origin)
    assert len(ours.triangles) > 100_000
    assert sc.surface_area(ours) == pytest.approx(sc.surface_area(theirs), rel=1e-3)
    assert sc.enclosed_volume(ours) == pytest.approx(sc.enclosed_volume(theirs), rel=1e-3)


@pytest.mark.parametrize("iso", [300.0, -300.0])
def test_flying_edges_agrees_in_area_volume_and_distance(ct_small, iso):
    ours = marching_cubes(ct_small.array, iso, spacing=ct_small.spacing, origin=ct_small.origin)
    flying = vtk_contour(ct_small.array, iso, ct_small.spacing, ct_small.origin, algorithm=vtkFlyingEdges3D)
    assert sc.surface_area(ours) == pytest.approx(sc.surface_area(flying), rel=1e-3)
    assert sc.enclosed_volume(ours) == pytest.approx(sc.enclosed_volume(flying), rel=1e-3)
    distance = sc.hausdorff(ours, flying)
    assert distance.hausdorff < 0.01 * min(ct_small.spacing)  # mm: the same surface up to rounding


# --------------------------------------------------------------------------------------------------------------
# Analytic surfaces and topology
# --------------------------------------------------------------------------------------------------------------
def test_sphere_area_volume_and_topology():
    radius = 12.0
    mesh = marching_cubes(sphere_field((36, 36, 36), radius), 0.0)
    assert sc.surface_area(mesh) == pytest.approx(4 * np.pi * radius**2, rel=0.01)
    assert sc.enclosed_volume(mesh) == pytest.approx(4 / 3 * np.pi * radius**3, rel=0.01)
    report = sc.edge_manifoldness(mesh)
    assert report.watertight and report.manifold and report.consistently_oriented
    assert sc.connected_components(mesh) == 1
    assert sc.orientation_outward(mesh).outward


def test_ellipsoid_with_anisotropic_spacing():
    semi_axes, spacing = (20.0, 14.0, 9.0), (0.8, 1.0, 1.3)
    shape = tuple(int(2 * s / d) + 6 for s, d in zip(semi_axes[::-1], spacing[::-1]))
    mesh = marching_cubes(ellipsoid_field(shape, semi_axes, spacing), 0.0, spacing=spacing)
    assert sc.surface_area(mesh) == pytest.approx(ellipsoid_area(*semi_axes), rel=0.01)
    assert sc.enclosed_volume(mesh) == pytest.approx(4 / 3 * np.pi * np.prod(semi_axes), rel=0.01)
    # centred: the grid centre is at origin + spacing * (n - 1) / 2
    centre = np.asarray(spacing) * (np.asarray(shape[::-1]) - 1) / 2
    assert np.allclose(mesh.points.mean(axis=0), centre, atol=0.05)


def test_torus_area_volume_and_genus():
    major, minor, spacing = 12.0, 4.5, (0.5, 0.5, 0.5)
    mesh = marching_cubes(torus_field((26, 72, 72), major, minor, spacing), 0.0, spacing=spacing)
    assert sc.surface_area(mesh) == pytest.approx(4 * np.pi**2 * major * minor, rel=0.01)
    assert sc.enclosed_volume(mesh) == pytest.approx(2 * np.pi**2 * major * minor**2, rel=0.01)
    points, triangles = sc.surface_arrays(mesh)
    edges = sc.edge_manifoldness(mesh)
    assert edges.watertight and edges.manifold
    assert len(points) - edges.edges + len(triangles) == 0  # Euler characteristic of a torus


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_closed_random_fields_are_watertight_manifold_and_outward(seed):
    field = closed_random_field(np.random.default_rng(seed))
    mesh = marching_cubes(field, 500.5)
    report = sc.edge_manifoldness(mesh)
    assert report.watertight and report.manifold and report.consistently_oriented, report
    assert sc.orientation_outward(mesh).outward


def test_hollow_shell_faces_away_from_the_solid():
    shell = np.minimum(sphere_field((40, 40, 40), 15.0), -sphere_field((40, 40, 40), 8.0))
    mesh = marching_cubes(shell, 0.0)
    orientation = sc.orientation_outward(mesh)
    assert orientation.outward and orientation.components == 2
    assert sorted(orientation.volumes) == pytest.approx([-4 / 3 * np.pi * 8.0**3, 4 / 3 * np.pi * 15.0**3], rel=0.02)


def test_surface_open_at_the_volume_border():
    mesh = marching_cubes(sphere_field((30, 40, 40), 16.0), 0.0)  # the sphere is cut by the k faces
    report = sc.edge_manifoldness(mesh)
    assert report.boundary_edges > 0 and report.manifold and report.consistently_oriented


# --------------------------------------------------------------------------------------------------------------
# Normals
# --------------------------------------------------------------------------------------------------------------
def test_normals_point_outward_along_the_radius():
    radius, shape = 10.0, (30, 30, 30)
    mesh = marching_cubes(sphere_field(shape, radius), 0.0, normals=True)
    radial = mesh.points - (np.asarray(shape[::-1]) - 1) / 2
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-6)
    assert np.degrees(np.arccos(np.clip((radial * mesh.normals).sum(axis=1), -1, 1))).max() < 2.0


def test_normals_match_vtk_with_anisotropic_spacing(ct_small):
    ours = marching_cubes(ct_small.array, 300.5, spacing=ct_small.spacing, origin=ct_small.origin, normals=True)
    output = vtk_contour(ct_small.array, 300.5, ct_small.spacing, ct_small.origin, normals=True)
    points, _ = polydata_arrays(output)
    normals = numpy_support.vtk_to_numpy(output.GetPointData().GetNormals())
    _, match = cKDTree(points).query(ours.points)
    assert np.abs(ours.normals - normals[match]).max() < 1e-5


def test_normals_agree_with_the_winding(ct_small):
    mesh = marching_cubes(ct_small.array, 300.5, spacing=ct_small.spacing, origin=ct_small.origin, normals=True)
    p0, p1, p2 = (mesh.points[mesh.triangles[:, c]].astype(np.float64) for c in range(3))
    facing = np.cross(p1 - p0, p2 - p0)
    vertex_normals = mesh.normals[mesh.triangles].mean(axis=1)
    assert np.mean((facing * vertex_normals).sum(axis=1) > 0) > 0.99


# --------------------------------------------------------------------------------------------------------------
# Preview, several isovalues, dtypes
# --------------------------------------------------------------------------------------------------------------
def test_stride_is_marching_cubes_on_every_other_sample():
    radius, field = 14.0, sphere_field((41, 41, 41), 14.0)
    full = marching_cubes(field, 0.0, spacing=(0.5, 0.5, 0.5))
    for stride in (2, 4):
        preview = marching_cubes(field, 0.0, spacing=(0.5, 0.5, 0.5), stride=stride)
        direct = marching_cubes(field[::stride, ::stride, ::stride], 0.0, spacing=(0.5 * stride,) * 3)
        assert np.array_equal(preview.points, direct.points) and np.array_equal(preview.triangles, direct.triangles)
        assert sc.surface_area(preview) == pytest.approx(4 * np.pi * (radius * 0.5) ** 2, rel=0.03)
        assert 0.5 / stride**2 < len(preview.triangles) / len(full.triangles) < 2.0 / stride**2


def test_several_isovalues_match_vtk_and_separate_runs():
    field = sphere_field((30, 30, 30), 12.0)
    levels = [0.0, 3.0, 6.5]
    mesh = marching_cubes(field, levels)
    offset = 0
    for level in levels:
        single = marching_cubes(field, level)
        assert np.all(mesh.values[offset:offset + len(single.points)] == np.float32(level))
        offset += len(single.points)
    assert offset == len(mesh.points)
    points, triangles = polydata_arrays(vtk_contour(field, levels))
    ambiguous = np.zeros(np.array(field.shape) - 1, dtype=bool)
    for level in levels:
        ambiguous |= np.isin(cell_cases(field, level), AMBIGUOUS_FACE_CASES)
    keep_ours = off_ambiguous_cells(mesh.points, mesh.triangles, ambiguous, (1, 1, 1), (0, 0, 0))
    keep_theirs = off_ambiguous_cells(points, triangles, ambiguous, (1, 1, 1), (0, 0, 0))
    comparison = sc.same_triangles(mesh.points, mesh.triangles[keep_ours], points, triangles[keep_theirs])
    assert comparison.equal, comparison.summary()
    assert sc.connected_components(mesh) == 3


@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.float32, np.float64, bool])
def test_dtypes_give_the_same_mesh(dtype):
    values = np.random.default_rng(5).integers(0, 2, size=(9, 10, 11))
    reference = marching_cubes(values.astype(np.int16), 0.5)
    mesh = marching_cubes(values.astype(dtype), 0.5)
    assert np.array_equal(mesh.points, reference.points) and np.array_equal(mesh.triangles, reference.triangles)


def test_isovalue_outside_an_integer_range_gives_an_empty_mesh():
    volume = np.random.default_rng(0).integers(0, 256, size=(6, 6, 6)).astype(np.uint8)
    for iso in (300.0, -1.0):
        mesh = marching_cubes(volume, iso, normals=True)
        assert mesh.points.shape == (0, 3) and mesh.triangles.shape == (0, 3) and mesh.normals.shape == (0, 3)


def test_float32_threshold_is_exact():
    """A float32 sample just below a float64 isovalue is outside even though it rounds to the same float32."""
    volume = np.zeros((3, 3, 3), dtype=np.float32)
    volume[1, 1, 1] = np.float32(0.1)  # 0.100000001490116...
    assert marching_cubes(volume, 0.1).triangles.shape[0] == 8  # inside: float64(0.1f) >= 0.1
    assert marching_cubes(volume, float(np.float32(0.1)) + 1e-12).triangles.shape[0] == 0


# --------------------------------------------------------------------------------------------------------------
# Parallel execution
# --------------------------------------------------------------------------------------------------------------
def test_slab_partition_does_not_change_the_mesh():
    """The fill pass gives the same vertices and triangles for any split of the layers into slabs, including empty
    slabs and one-layer slabs, run concurrently: each edge row's vertices are numbered from its prefix sum, so
    the rows of cells sharing an edge row agree without talking to each other, and every slot is written once."""
    field = np.random.default_rng(11).integers(0, 1000, size=(12, 9, 10)).astype(np.int16)
    threshold = core._inside_threshold(field.dtype, 500.5)
    counts = core._count(field, threshold, None)
    assert counts.spans.shape == (11, 8, 2) and counts.edges.shape == (12, 9, 3)
    inside = field >= 500.5
    # The counting pass owns every edge row exactly once: its counts are the cut edges of that row.
    assert np.array_equal(counts.edges[:, :, 0], (inside[:, :, 1:] != inside[:, :, :-1]).sum(axis=2))
    assert np.array_equal(counts.edges[:, :-1, 1], (inside[:, 1:, :] != inside[:, :-1, :]).sum(axis=2))
    assert np.array_equal(counts.edges[:-1, :, 2], (inside[1:] != inside[:-1]).sum(axis=2))
    assert not counts.edges[:, -1, 1].any() and not counts.edges[-1, :, 2].any()
    vertex_first = np.cumsum(counts.edges.ravel()).reshape(counts.edges.shape) - counts.edges
    triangle_first = np.cumsum(counts.triangles.ravel()).reshape(counts.triangles.shape) - counts.triangles
    vertices, triangle_total = int(counts.edges.sum()), int(counts.triangles.sum())
    results = []
    for bounds, parts in (([0, 11], 1), ([0, 1, 1, 4, 5, 9, 11, 11], 2), ([0, 0, 11], 3), (list(range(12)), 2),
                          (list(range(12)), 5)):
        points = np.full((vertices, 3), np.nan, dtype=np.float32)
        on_sample = np.full(vertices, -7, dtype=np.int64)
        triangles = np.full((triangle_total, 3), -1, dtype=np.int64)
        kernels.fill_layers(field, threshold, 500.5, np.array(bounds, dtype=np.int64), parts, counts.spans,
                            vertex_first, triangle_first, kernels.PAIR_CASE, kernels.TRIANGLES,
                            kernels.TRIANGLE_COUNT, np.ones(3), np.zeros(3), points, np.empty((0, 3), np.float32),
                            on_sample, triangles)
        results.append((points, on_sample, triangles))
    # The counting pass gives the same counts whatever the number of threads taking its layers.
    for parts in (1, 3, 16):
        spans = np.empty_like(counts.spans)
        edges = np.zeros_like(counts.edges)
        triangle_counts = np.empty_like(counts.triangles)
        flags = np.zeros(field.shape[0] - 1, dtype=np.bool_)
        kernels.count_layers(field, threshold, 0, field.shape[0] - 1, parts, kernels.PAIR_CASE,
                             kernels.TRIANGLE_COUNT, spans, edges, triangle_counts, flags)
        assert np.array_equal(spans, counts.spans) and np.array_equal(edges, counts.edges)
        assert np.array_equal(triangle_counts, counts.triangles) and not flags.any()
    reference_points, reference_on_sample, reference_triangles = results[0]
    assert not np.isnan(reference_points).any() and reference_on_sample.min() == -1  # every vertex placed once
    assert reference_triangles.min() >= 0 and np.array_equal(np.unique(reference_triangles), np.arange(vertices))
    for points, on_sample, triangles in results[1:]:
        assert np.array_equal(points, reference_points) and np.array_equal(triangles, reference_triangles)
        assert np.array_equal(on_sample, reference_on_sample)


def test_count_triangles_is_the_triangles_before_merging(ct_small):
    field = np.random.default_rng(3).integers(0, 1000, size=(12, 9, 10)).astype(np.int16)
    assert count_triangles(field, 500.5) == len(marching_cubes(field, 500.5).triangles)
    # On a sample equal to the isovalue collapsed triangles are dropped: the count is an upper bound.
    exact = count_triangles(ct_small.array, 300.0)
    assert exact >= len(marching_cubes(ct_small.array, 300.0).triangles) > 0.99 * exact
    assert count_triangles(ct_small.array, 300.5, stride=2) == len(marching_cubes(ct_small.array, 300.5,
                                                                                   stride=2).triangles)
    assert count_triangles(ct_small.array, 40000.0) == 0
    with pytest.raises(ValueError, match="one isovalue"):
        count_triangles(field, [1.0, 2.0])


def test_long_rows_are_not_limited():
    """Vertices are numbered per edge row, not packed into bit fields: a row of 70,000 samples is fine."""
    field = np.zeros((2, 2, 70000), dtype=np.uint8)
    field[:, :, 30000:40000] = 1
    mesh = marching_cubes(field, 0.5)
    assert len(mesh.triangles) > 0 and sc.edge_manifoldness(mesh.points, mesh.triangles).manifold
    assert mesh.points[:, 0].min() == 29999.5 and mesh.points[:, 0].max() == 39999.5


def test_parallel_and_serial_runs_agree(ct_small, monkeypatch):
    serial = marching_cubes(ct_small.array, 300.0, spacing=ct_small.spacing, normals=True)
    monkeypatch.setattr(core, "PARALLEL_MIN_SAMPLES", 0)  # the small phantom on all threads
    parallel = marching_cubes(ct_small.array, 300.0, spacing=ct_small.spacing, normals=True)
    for name in ("points", "triangles", "normals", "values"):
        assert np.array_equal(getattr(serial, name), getattr(parallel, name)), name


# --------------------------------------------------------------------------------------------------------------
# Progress, cancellation and errors
# --------------------------------------------------------------------------------------------------------------
def test_progress_is_reported_and_cancellation_propagates():
    field = sphere_field((20, 20, 20), 6.0)
    seen = []
    marching_cubes(field, [0.0, 2.0], progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) >= 4

    def cancel(fraction):
        if fraction > 0.2:
            raise OperationCancelled("stop")

    with pytest.raises(OperationCancelled):
        marching_cubes(field, 0.0, progress=cancel)


@pytest.mark.parametrize(
    "volume, level, options, message",
    [
        (np.zeros((4, 4)), 0.5, {}, "3D array"),
        (np.zeros((4, 4, 4), dtype=complex), 0.5, {}, "real scalar"),
        (np.zeros((1, 4, 4)), 0.5, {}, "at least 2 samples"),
        (np.zeros((2, 4, 4)), 0.5, {"stride": 2}, "after stride 2"),
        (np.full((3, 3, 3), np.nan, dtype=np.float32), 0.5, {}, "NaN"),
        (np.zeros((3, 3, 3)), [], {}, "one isovalue or a sequence"),
        (np.zeros((3, 3, 3)), [[0.5]], {}, "one isovalue or a sequence"),
        (np.zeros((3, 3, 3)), np.inf, {}, "finite"),
        (np.zeros((3, 3, 3)), [0.5, 0.5], {}, "distinct"),
        (np.zeros((3, 3, 3)), 0.5, {"spacing": (1.0, 1.0)}, "spacing must be three"),
        (np.zeros((3, 3, 3)), 0.5, {"spacing": (1.0, 0.0, 1.0)}, "positive"),
        (np.zeros((3, 3, 3)), 0.5, {"origin": (0.0, np.nan, 0.0)}, "origin must be three finite"),
        (np.zeros((3, 3, 3)), 0.5, {"stride": 0}, "stride must be a positive integer"),
        (np.zeros((3, 3, 3)), 0.5, {"stride": 1.5}, "stride must be a positive integer"),
        (np.zeros((3, 3, 3)), 0.5, {"stride": True}, "stride must be a positive integer"),
    ],
)
def test_value_errors(volume, level, options, message):
    with pytest.raises(ValueError, match=message):
        marching_cubes(volume, level, **options)


# --------------------------------------------------------------------------------------------------------------
# The VTK filter
# --------------------------------------------------------------------------------------------------------------
def test_filter_matches_the_core_and_places_the_output_like_vtk():
    field = sphere_field((18, 20, 22), 6.0)
    image = image_from_array(field, (0.5, 1.0, 1.5), (10.0, -5.0, 2.0))
    image.SetExtent(3, 24, -2, 17, 1, 18)  # same size, shifted extent: VTK places index (3, -2, 1) at the origin...
    image.SetDirectionMatrix(0, -1, 0, 1, 0, 0, 0, 0, 1)  # ...and rotates by the direction matrix
    contour = MarchingCubesFilter()
    contour.SetInputDataObject(image)
    contour.SetValue(0, 0.0)
    ours = run_algorithm(contour)
    reference = vtkMarchingCubes()
    reference.SetInputData(image)
    reference.SetValue(0, 0.0)
    theirs = run_algorithm(reference)
    comparison = sc.same_triangles(*polydata_arrays(ours), *polydata_arrays(theirs))
    assert comparison.equal, comparison.summary()
    ours_normals = numpy_support.vtk_to_numpy(ours.GetPointData().GetNormals())
    their_normals = numpy_support.vtk_to_numpy(theirs.GetPointData().GetNormals())
    _, match = cKDTree(polydata_arrays(theirs)[0]).query(polydata_arrays(ours)[0])
    assert np.abs(ours_normals - their_normals[match]).max() < 1e-5
    assert ours.GetPointData().GetScalars().GetName() == "scalars"


def test_filter_contour_values_normals_and_stride():
    contour = MarchingCubesFilter()
    assert contour.GetNumberOfContours() == 1 and contour.GetComputeNormals()
    contour.SetValue(2, 4.0)
    assert contour.GetValues() == (0.0, 0.0, 4.0)
    contour.SetNumberOfContours(2)
    assert contour.GetValues() == (0.0, 0.0)
    before = contour.GetMTime()
    contour.SetValue(1, 0.0)
    contour.SetComputeNormals(True)
    contour.SetStride(1)
    assert contour.GetMTime() == before  # unchanged values do not modify the filter
    contour.SetValue(1, 3.0)
    contour.ComputeNormalsOff()
    contour.SetStride(2)
    assert contour.GetMTime() > before
    field = sphere_field((21, 21, 21), 8.0)
    contour.SetInputDataObject(image_from_array(field))
    output = run_algorithm(contour)
    assert output.GetPointData().GetNormals() is None
    expected = marching_cubes(field, [0.0, 3.0], stride=2)
    assert output.GetNumberOfCells() == len(expected.triangles)
    with pytest.raises(ValueError):
        contour.SetStride(0)
    with pytest.raises(ValueError):
        contour.SetValue(-1, 0.0)


def test_filter_contour_values_live_in_a_vtk_contour_values():
    """The contour values are a vtkContourValues; changing one, through the filter or directly, runs it again."""
    field = sphere_field((21, 21, 21), 8.0)
    contour = MarchingCubesFilter()
    contour.SetInputDataObject(image_from_array(field))
    values = contour.GetContourValues()
    assert isinstance(values, vtkContourValues) and values.GetNumberOfContours() == 1 and values.GetValue(0) == 0.0
    output = run_algorithm(contour)
    first = (output.GetMTime(), output.GetNumberOfPoints())
    run_algorithm(contour)
    contour.SetValue(0, 0.0)  # unchanged: no new run
    assert (run_algorithm(contour).GetMTime(), output.GetNumberOfPoints()) == first
    before = contour.GetMTime()
    contour.SetValue(0, 3.0)
    assert contour.GetMTime() > before
    output = run_algorithm(contour)
    assert output.GetMTime() > first[0] and output.GetNumberOfCells() == len(marching_cubes(field, 3.0).triangles)
    stamp = output.GetMTime()
    values.SetValue(0, 5.0)  # directly on the vtkContourValues: GetMTime follows it, and the pipeline runs again
    assert contour.GetMTime() >= values.GetMTime()
    output = run_algorithm(contour)
    assert output.GetMTime() > stamp and output.GetNumberOfCells() == len(marching_cubes(field, 5.0).triangles)
    contour.GenerateValues(3, 0.0, 4.0)
    assert contour.GetValues() == (0.0, 2.0, 4.0) and contour.GetNumberOfContours() == 3
    output = run_algorithm(contour)
    expected = marching_cubes(field, [0.0, 2.0, 4.0], normals=True)
    assert output.GetNumberOfCells() == len(expected.triangles)
    comparison = sc.same_triangles(*polydata_arrays(output), expected.points, expected.triangles)
    assert comparison.equal, comparison.summary()
    isovalues = numpy_support.vtk_to_numpy(output.GetPointData().GetScalars())
    assert np.array_equal(isovalues, expected.values)
    contour.SetNumberOfContours(0)
    assert run_algorithm(contour).GetNumberOfCells() == 0
    with pytest.raises(IndexError):
        contour.GetValue(0)


def test_filter_reports_errors_progress_and_cancellation():
    contour = MarchingCubesFilter()
    contour.SetInputDataObject(image_from_array(sphere_field((16, 16, 16), 5.0)))
    contour.SetValue(0, 0.0)
    contour.SetValue(1, 0.0)
    with pytest.raises(VTKError, match="distinct"):
        run_algorithm(contour)
    contour.SetNumberOfContours(1)
    seen = []
    output = run_algorithm(contour, seen.append)
    assert output.GetNumberOfCells() > 0 and seen[-1] == 1.0

    def cancel(fraction):
        if fraction > 0.1:
            raise OperationCancelled("stop")

    contour.Modified()
    with pytest.raises(OperationCancelled):
        run_algorithm(contour, cancel)


def test_mesh_to_polydata_round_trip():
    mesh = marching_cubes(sphere_field((12, 12, 12), 4.0), [0.0, 1.0], normals=True)
    assert isinstance(mesh, MarchingCubesMesh)
    polydata = mesh.to_polydata()
    points, triangles = polydata_arrays(polydata)
    assert np.array_equal(points, mesh.points) and np.array_equal(triangles, mesh.triangles)
    assert np.array_equal(numpy_support.vtk_to_numpy(polydata.GetPointData().GetScalars()), mesh.values)
    assert np.array_equal(numpy_support.vtk_to_numpy(polydata.GetPointData().GetNormals()), mesh.normals)
