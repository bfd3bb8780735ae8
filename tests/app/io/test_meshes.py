"""Meshes as input: every format and its .gz, counts and topology flags, real meshes, damaged files."""

from __future__ import annotations

import gzip
import os
import struct
from pathlib import Path

import numpy as np
import pytest

from app.io import MESH_SUFFIXES_READ, MeshReadError, describe_mesh, is_mesh_path, load_mesh, load_volume
from app.io.errors import UnsupportedFormatError

from .mesh_samples import combined, cube, icosphere, triangles_of, write_mesh, write_obj, write_ply, write_stl

KINDS = ["stl", "ascii.stl", "obj", "ply", "ascii.ply", "vtp", "off"]
#: Formats that store polygons as they are (STL stores triangles only).
POLYGON_KINDS = ["obj", "ply", "ascii.ply", "vtp", "off"]
REPO = Path(__file__).resolve().parents[3]
SHARED_MESHES = REPO.parent / "shared" / "data" / "meshes"


def _sphere():
    return icosphere(2, radius=10.0)


def _with_hole():
    points, faces = _sphere()
    return points, faces[1:]  # one triangle missing: a hole with 3 boundary edges


def _flipped():
    points, faces = _sphere()
    return points, [f[::-1] for f in faces]


def _mixed():
    points, faces = _sphere()
    return points, [faces[0][::-1]] + faces[1:]


def _two_spheres():
    return combined(icosphere(1, 5.0, (0, 0, 0)), icosphere(1, 5.0, (20, 0, 0)))


def _touching_cubes():
    # Two closed cubes sharing exactly one corner point: one vertex-connected piece with a pinched vertex.
    return combined(cube(2.0, (0, 0, 0)), cube(2.0, (2, 2, 2)))


def _fin():
    # A cube with an extra triangle standing on one of its edges: that edge has three triangles.
    points, faces = cube(2.0)
    points = np.vstack([points, [[1.0, -3.0, 0.0]]])
    return points, faces + [[0, 1, 8]]


SHAPES = {
    # name: (builder, points, triangles, closed, boundary, non-manifold edges, components, orientation)
    "sphere": (_sphere, 162, 320, True, 0, 0, 1, "outward"),
    "hole": (_with_hole, 162, 319, False, 3, 0, 1, "undefined"),
    "flipped": (_flipped, 162, 320, True, 0, 0, 1, "inward"),
    "mixed": (_mixed, 162, 320, True, 0, 0, 1, "mixed"),
    "two-spheres": (_two_spheres, 84, 160, True, 0, 0, 2, "outward"),
    "touching-cubes": (_touching_cubes, 15, 24, True, 0, 0, 1, "outward"),
    "fin": (_fin, 9, 13, False, 2, 1, 1, "undefined"),  # the fin makes the only piece open
    "quad-cube": (lambda: cube(2.0, quads=True), 8, 12, True, 0, 0, 1, "outward"),
}


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gz"])
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("shape", list(SHAPES))
def test_every_format_reads_back_with_the_right_counts_and_flags(tmp_path, shape, kind, gz):
    builder, points, triangles, closed, boundary, fins, components, orientation = SHAPES[shape]
    source_points, faces = builder()
    path = write_mesh(tmp_path, shape, kind, source_points, faces, gz=gz)
    mesh = load_mesh(path)
    facts = describe_mesh(mesh)
    assert facts["kind"] == "mesh"
    assert facts["source_format"].startswith("STL" if "stl" in kind else kind.split(".")[-1].upper())
    assert facts["source_format"].endswith("(gzip)") == gz
    assert (facts["points"], facts["triangles"]) == (points, triangles)
    assert facts["closed"] is closed
    assert facts["boundary_edges"] == boundary
    assert facts["non_manifold_edges"] == fins
    assert facts["components"] == components
    assert facts["orientation"] == orientation
    low, high = source_points.min(axis=0), source_points.max(axis=0)
    assert np.allclose(facts["bounds"], [low[0], high[0], low[1], high[1], low[2], high[2]], atol=1e-5)
    if closed and orientation in ("outward", "inward") and fins == 0:
        assert facts["volume_mm3"] > 0
    else:
        assert facts["volume_mm3"] is None


def test_values_of_a_closed_cube(tmp_path):
    mesh = load_mesh(write_mesh(tmp_path, "cube", "off", *cube(3.0, quads=True)))
    facts = describe_mesh(mesh)
    assert facts["volume_mm3"] == pytest.approx(27.0)
    assert facts["area_mm2"] == pytest.approx(54.0)
    assert facts["non_manifold_vertices"] == 0
    assert mesh.triangles.shape == (12, 3) and mesh.points.shape == (8, 3)


def test_touching_cubes_report_the_pinched_vertex(tmp_path):
    facts = describe_mesh(load_mesh(write_mesh(tmp_path, "touch", "obj", *_touching_cubes())))
    assert facts["non_manifold_vertices"] == 1
    assert facts["volume_mm3"] == pytest.approx(16.0)


def test_polygons_are_triangulated_and_points_merged(tmp_path):
    # A hexagonal prism written with hexagons and quads, every face with its own copy of its corners.
    angles = np.radians(np.arange(0, 360, 60))
    ring = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(6)])
    points = np.vstack([ring, ring + [0, 0, 2]])
    faces = [[5, 4, 3, 2, 1, 0], [6, 7, 8, 9, 10, 11]] + [[i, (i + 1) % 6, (i + 1) % 6 + 6, i + 6] for i in range(6)]
    separate = np.vstack([points[f] for f in faces])
    starts = np.cumsum([0] + [len(f) for f in faces])
    split_faces = [list(range(starts[i], starts[i + 1])) for i in range(len(faces))]
    mesh = load_mesh(write_mesh(tmp_path, "prism", "obj", separate, split_faces))
    facts = describe_mesh(mesh)
    assert (facts["points"], facts["triangles"]) == (12, 2 * 4 + 6 * 2)
    assert facts["closed"] and facts["orientation"] == "outward"
    assert facts["volume_mm3"] == pytest.approx(3 * np.sqrt(3) / 2 * 2, rel=1e-6)


def test_degenerate_triangles_lines_and_vertices_are_dropped_and_counted(tmp_path):
    points, faces = cube(2.0)
    text = write_obj(tmp_path / "c.obj", points, faces).read_text()
    text += "f 1 1 2\nl 1 2\np 3\n"
    (tmp_path / "c.obj").write_text(text)
    mesh = load_mesh(tmp_path / "c.obj")
    assert describe_mesh(mesh)["triangles"] == 12
    joined = " ".join(mesh.warnings)
    assert "1 degenerate triangle(s) dropped" in joined
    assert "line cell(s) dropped" in joined and "vertex cell(s) dropped" in joined


def test_mesh_suffixes_and_dispatch(tmp_path):
    assert set(MESH_SUFFIXES_READ) >= {".stl", ".obj", ".ply", ".vtp", ".off", ".stl.gz", ".off.gz"}
    assert is_mesh_path("a/b/Bunny.OBJ.gz") and is_mesh_path("x.stl") and not is_mesh_path("x.nii.gz")
    assert not is_mesh_path("x.vtk") and not is_mesh_path("folder")
    path = write_mesh(tmp_path, "cube", "stl", *cube())
    with pytest.raises(UnsupportedFormatError, match=r"cube-stl\.stl: this is a surface mesh, not a volume"):
        load_volume(path)


# ----------------------------------------------------------------------------------------------------------------
# Real meshes (../shared/data/meshes, next to the repository)
# ----------------------------------------------------------------------------------------------------------------
REAL = {
    "stanford-bunny.obj.gz": (69451, False, 223),
    "spot.obj.gz": (5856, True, 0),
    "fandisk.obj.gz": (12946, True, 0),
    "cow.obj.gz": (5804, True, 0),
}


@pytest.mark.parametrize("name", list(REAL))
def test_real_meshes(name):
    if not SHARED_MESHES.is_dir():
        pytest.skip(f"the real test meshes are not here: {SHARED_MESHES} is missing (CI has ../shared next to the "
                    "repository)")
    triangles, closed, boundary = REAL[name]
    facts = describe_mesh(load_mesh(SHARED_MESHES / name))
    assert facts["triangles"] == triangles
    assert facts["closed"] is closed and facts["boundary_edges"] == boundary
    assert facts["non_manifold_edges"] == 0 and facts["components"] == 1
    assert facts["orientation"] == ("outward" if closed else "undefined")
    assert (facts["volume_mm3"] is not None) == closed


def test_the_bunny_has_five_holes():
    if not SHARED_MESHES.is_dir():
        pytest.skip(f"the real test meshes are not here: {SHARED_MESHES} is missing")
    from algorithms.compare.topology import edge_manifoldness

    mesh = load_mesh(SHARED_MESHES / "stanford-bunny.obj.gz")
    points, tris = mesh.points, mesh.triangles
    # Boundary edges form closed loops, one per hole.
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    rim = unique[counts == 1]
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(rim)), (rim[:, 0], rim[:, 1])), shape=(len(points),) * 2)
    labels = connected_components(graph, directed=False)[1]
    assert len(np.unique(labels[rim[:, 0]])) == 5
    assert edge_manifoldness(points, tris).boundary_edges == 223


# ----------------------------------------------------------------------------------------------------------------
# Damaged files
# ----------------------------------------------------------------------------------------------------------------
def _assert_refused(path, pattern: str):
    with pytest.raises(MeshReadError) as caught:
        load_mesh(path)
    message = str(caught.value)
    assert path.name in message and "\n" not in message, message
    assert not getattr(caught.value, "unexpected", False), message
    import re

    assert re.search(pattern, message), message


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply", ".vtp", ".off", ".obj.gz"])
def test_empty_files(tmp_path, suffix):
    path = tmp_path / f"empty{suffix}"
    path.write_bytes(b"")
    _assert_refused(path, "empty")


def test_no_points_and_no_faces(tmp_path):
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    _assert_refused(tmp_path / "points.obj", "no faces")
    (tmp_path / "comments.obj").write_text("# nothing here\n# at all\n")
    _assert_refused(tmp_path / "comments.obj", "no vertices")
    (tmp_path / "zero.stl").write_bytes(b"\0" * 80 + struct.pack("<I", 0))
    _assert_refused(tmp_path / "zero.stl", "no triangles")
    write_ply(tmp_path / "nofaces.ply", np.eye(3), [], binary=False)
    _assert_refused(tmp_path / "nofaces.ply", "no faces")
    (tmp_path / "nothing.off").write_text("OFF\n0 0 0\n")
    _assert_refused(tmp_path / "nothing.off", "declares 0 vertices")


def test_non_finite_coordinates(tmp_path):
    points, faces = cube()
    bad = points.copy()
    bad[3] = [np.nan, 0, 0]
    for kind in ("stl", "obj", "off", "ascii.ply", "vtp"):
        path = write_mesh(tmp_path, "nan", kind, bad, faces)
        _assert_refused(path, "NaN or infinite|non-finite")
    bad[3] = [np.inf, 0, 0]
    _assert_refused(write_mesh(tmp_path, "inf", "ply", bad, faces), "NaN or infinite")


def test_face_indices_out_of_range(tmp_path):
    points, faces = cube()
    broken = faces[:-1] + [[0, 1, 42]]
    _assert_refused(write_mesh(tmp_path, "range", "obj", points, broken), "face index 43 names no vertex")
    _assert_refused(write_mesh(tmp_path, "range", "off", points, broken), "names vertex 42 of 8")
    _assert_refused(write_mesh(tmp_path, "range", "ascii.ply", points, broken), "index out of range")
    _assert_refused(write_mesh(tmp_path, "range", "ply", points, broken), "index out of range")
    (tmp_path / "negative.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9\n")
    _assert_refused(tmp_path / "negative.obj", "face index -9 names no vertex")
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    _assert_refused(tmp_path / "zero.obj", "face index 0 names no vertex")


def test_truncated_files(tmp_path):
    points, faces = icosphere(1)
    stl = write_mesh(tmp_path, "cut", "stl", points, faces)
    stl.write_bytes(stl.read_bytes()[:-75])
    _assert_refused(stl, r"declares 80 triangles \(4084 bytes\) but the file has 4009 bytes \(truncated\)")
    padded = write_mesh(tmp_path, "pad", "stl", points, faces)
    padded.write_bytes(padded.read_bytes() + b"\0" * 7)
    _assert_refused(padded, "7 bytes longer")
    ascii_stl = write_mesh(tmp_path, "cut", "ascii.stl", points, faces)
    ascii_stl.write_text(ascii_stl.read_text()[:-300])
    _assert_refused(ascii_stl, "no 'endsolid' line")
    for kind in ("ply", "ascii.ply"):
        ply = write_mesh(tmp_path, "cut", kind, points, faces)
        ply.write_bytes(ply.read_bytes()[:-20])
        _assert_refused(ply, "truncated")
    off = write_mesh(tmp_path, "cut", "off", points, faces)
    off.write_text("\n".join(off.read_text().splitlines()[:-5]))
    _assert_refused(off, "truncated")
    vtp = write_mesh(tmp_path, "cut", "vtp", points, faces)
    vtp.write_bytes(vtp.read_bytes()[:-200])
    _assert_refused(vtp, "truncated|damaged|malformed")
    zipped = write_mesh(tmp_path, "cut", "obj", points, faces, gz=True)
    zipped.write_bytes(zipped.read_bytes()[:-30])
    _assert_refused(zipped, "truncated")
    crc = write_mesh(tmp_path, "crc", "obj", points, faces, gz=True)
    data = bytearray(crc.read_bytes())
    data[-6] ^= 0xFF  # the stored CRC
    crc.write_bytes(bytes(data))
    _assert_refused(crc, "damaged")


def test_text_garbage_and_binary_garbage(tmp_path):
    rng = np.random.default_rng(5)
    for suffix in (".stl", ".obj", ".ply", ".vtp", ".off"):
        text = tmp_path / f"text{suffix}"
        text.write_text("this is a shopping list\nmilk\neggs\n" * 5)
        _assert_refused(text, ".")
        binary = tmp_path / f"binary{suffix}"
        binary.write_bytes(rng.integers(0, 256, 3000, dtype=np.uint8).tobytes())
        _assert_refused(binary, ".")


def test_wrong_extension(tmp_path):
    points, faces = cube()
    ply = write_mesh(tmp_path, "real", "ply", points, faces)
    os.rename(ply, tmp_path / "named.stl")
    _assert_refused(tmp_path / "named.stl", "holds PLY data, not STL. Rename it with the PLY extension")
    obj = write_mesh(tmp_path, "real", "obj", points, faces)
    os.rename(obj, tmp_path / "named.off")
    _assert_refused(tmp_path / "named.off", "not OFF")
    stl = write_stl(tmp_path / "x.stl", points, faces)
    (tmp_path / "named.obj.gz").write_bytes(gzip.compress(stl.read_bytes()))
    _assert_refused(tmp_path / "named.obj.gz", "holds STL data, not OBJ")


def test_special_files_are_refused(tmp_path):
    fifo = tmp_path / "pipe.stl"
    os.mkfifo(fifo)
    _assert_refused(fifo, "FIFO")
    _assert_refused(Path("/dev/zero.stl") if Path("/dev/zero.stl").exists() else tmp_path / "missing.stl", "no such")


def test_a_gzip_bomb_is_capped(tmp_path, monkeypatch):
    from app.io import safety

    monkeypatch.setattr(safety, "memory_override", 64 << 20)  # pretend 64 MiB are available: cap 16 MiB
    bomb = tmp_path / "bomb.stl.gz"
    with gzip.open(bomb, "wb") as stream:
        for _ in range(40):
            stream.write(bytes(1 << 20))
    _assert_refused(bomb, "inflates to more than")


def test_triangles_match_the_faces_written(tmp_path):
    points, faces = icosphere(1)
    mesh = load_mesh(write_mesh(tmp_path, "s", "ply", points, faces))
    written = {tuple(np.round(points[t], 6).ravel()) for t in triangles_of(faces)}
    read = {tuple(np.round(mesh.points[t], 6).ravel()) for t in mesh.triangles}
    assert read == written  # same corners in the same cyclic order (winding kept)
