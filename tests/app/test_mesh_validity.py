"""The lean validity report (:mod:`app.mesh_validity`) gives the answers of :mod:`algorithms.compare` - edges,
pinched vertices, pieces, closedness, nesting, orientation, area and volume - on meshes that exercise each rule:
random marching-cubes surfaces, voxel surfaces (edges in four triangles), pinched vertices, cavities and islands in
cavities, flipped and open meshes, several pieces, and the real meshes of ``../shared/data/meshes``; and it uses
a fraction of their memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from algorithms.compare import measures, topology
from algorithms.datasets.volumes import sphere_field
from algorithms.surfaces.marching_cubes import marching_cubes
from algorithms.surfaces.voxel_faces import voxel_faces
from app.mesh_validity import validity_numbers

MESHES = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "meshes"


def reference(points, triangles) -> dict:
    edges = topology.edge_manifoldness(points, triangles)
    orientation = topology.orientation_outward(points, triangles)
    return {"edges": edges, "components": orientation.components, "outward": orientation.outward,
            "area_mm2": measures.surface_area(points, triangles),
            "volume_mm3": measures.enclosed_volume(points, triangles),
            "volumes": np.sort(orientation.volumes), "depth": np.sort(orientation.depth),
            "closed": int(orientation.closed.sum())}


def check_same(points, triangles) -> dict:
    expected = reference(points, triangles)
    found = validity_numbers(points, triangles)
    assert found["edges"] == expected["edges"]
    assert found["components"] == expected["components"]
    assert found["outward"] == expected["outward"]
    assert found["area_mm2"] == pytest.approx(expected["area_mm2"], rel=1e-9)
    assert found["volume_mm3"] == pytest.approx(expected["volume_mm3"], rel=1e-9, abs=1e-9)
    np.testing.assert_allclose(np.sort(found["volumes"]), expected["volumes"], rtol=1e-9, atol=1e-9)
    assert np.array_equal(np.sort(found["depth"]), expected["depth"])
    assert int(found["closed"].sum()) == expected["closed"]
    return found


def ball(shape, radius, centre=None):
    k, j, i = np.indices(shape, dtype=np.float64)
    centre = np.asarray(centre if centre is not None else [(n - 1) / 2 for n in shape])
    return radius - np.sqrt((k - centre[0]) ** 2 + (j - centre[1]) ** 2 + (i - centre[2]) ** 2)


@pytest.mark.parametrize("seed", range(4))
def test_random_marching_cubes_surfaces(seed):
    field = np.random.default_rng(seed).standard_normal((14, 15, 16)).cumsum(axis=0)
    mesh = marching_cubes(field, 0.3)
    check_same(mesh.points, mesh.triangles)


def test_integer_field_with_pinched_vertices():
    field = (np.random.default_rng(5).random((12, 11, 10)) > 0.55).astype(np.int16)
    mesh = marching_cubes(field, 1.0)  # vertices on samples are merged: pinched
    found = check_same(mesh.points, mesh.triangles)
    assert found["edges"].nonmanifold_vertices > 0


def test_voxel_surfaces_with_edges_in_four_triangles():
    faces = voxel_faces(np.random.default_rng(2).random((9, 8, 10)) > 0.5)
    points, triangles = faces.points, faces.triangles
    # Merge the corners that voxel faces store apart, as an export does.
    unique, inverse = np.unique(points, axis=0, return_inverse=True)
    found = check_same(unique, inverse.reshape(-1)[triangles])
    assert found["edges"].nonmanifold_edges > 0 and found["edges"].watertight


def test_cavities_and_islands_nest():
    shape = (40, 40, 40)
    shell = np.minimum(ball(shape, 16.0), -ball(shape, 9.0))  # a hollow ball...
    solid = np.maximum(shell, ball(shape, 4.0))  # ...with an island in its cavity
    solid = np.maximum(solid, ball(shape, 2.5, (5, 5, 5)))  # and a separate pebble outside
    mesh = marching_cubes(solid, 0.0)
    found = check_same(mesh.points, mesh.triangles)
    assert found["components"] == 4 and found["outward"]
    assert sorted(found["depth"]) == [0, 0, 1, 2]
    flipped = mesh.triangles.copy()
    pieces = np.unique(found["depth"])
    flipped[: len(flipped) // 3] = flipped[: len(flipped) // 3, ::-1]  # some pieces turned inside out
    check_same(mesh.points, flipped)
    assert pieces.size == 3


def test_open_and_several_pieces():
    mesh = marching_cubes(sphere_field((20, 20, 20), 6.0), 0.0)
    found = check_same(mesh.points, mesh.triangles[:-40])
    assert not found["edges"].watertight and not found["closed"].all()
    two = np.concatenate([mesh.triangles, mesh.triangles + len(mesh.points)])
    found = check_same(np.concatenate([mesh.points, mesh.points + 30.0]), two)
    assert found["components"] == 2


def test_empty_and_unused_points():
    found = validity_numbers(np.zeros((5, 3)), np.empty((0, 3), dtype=np.int64))
    assert found["components"] == 0 and found["area_mm2"] == 0.0
    mesh = marching_cubes(sphere_field((16, 16, 16), 5.0), 0.0)
    extra = np.concatenate([mesh.points, np.full((3, 3), 99.0, dtype=np.float32)])
    check_same(extra, mesh.triangles)


@pytest.mark.parametrize("name", ["stanford-bunny.obj.gz", "spot.obj.gz", "fandisk.obj.gz", "cow.obj.gz"])
def test_real_meshes(name):
    path = MESHES / name
    if not path.exists():
        pytest.skip(f"{path} is not here (the shared data folder is absent)")
    from app.io.meshes import load_mesh

    mesh = load_mesh(path)
    check_same(mesh.points, mesh.triangles)


def test_memory_is_a_fraction_of_the_reference():
    """Peak of Python-tracked allocations (NumPy arrays) during the report, on a 0.3 M triangle surface."""
    import tracemalloc

    field = sphere_field((120, 120, 120), 50.0) + 0.8 * np.random.default_rng(0).standard_normal((120, 120, 120))
    mesh = marching_cubes(field.astype(np.float32), 0.0)
    points, triangles = mesh.points, mesh.triangles
    peaks = []
    for run in (lambda: validity_numbers(points, triangles),
                lambda: (topology.edge_manifoldness(points, triangles), topology.orientation_outward(points, triangles),
                         measures.surface_area(points, triangles), measures.enclosed_volume(points, triangles))):
        tracemalloc.start()
        try:
            run()
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    lean, full = peaks
    assert lean < 0.5 * full, (lean / len(triangles), full / len(triangles))
