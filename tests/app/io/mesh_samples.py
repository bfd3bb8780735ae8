"""Meshes made in code, and writers for every mesh format ``load_mesh`` reads (STL, OBJ, PLY, VTP, OFF, .gz).

Each sample is ``(points (n, 3), faces)``: ``faces`` a list of vertex-index lists (triangles or larger polygons),
so the same shape can be written with polygons where a format allows them.
"""

from __future__ import annotations

import gzip
import struct
from pathlib import Path

import numpy as np


def icosphere(subdivisions: int = 1, radius: float = 10.0, centre=(0.0, 0.0, 0.0)):
    """A closed sphere of triangles facing outward (an icosahedron subdivided ``subdivisions`` times)."""
    t = (1 + 5 ** 0.5) / 2
    points = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
              (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    points = [np.array(p, float) / np.linalg.norm(p) for p in points]
    for _ in range(subdivisions):
        cache: dict = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = points[a] + points[b]
                points.append(m / np.linalg.norm(m))
                cache[key] = len(points) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(points) * radius + np.asarray(centre, float), [list(f) for f in faces]


def cube(size: float = 2.0, origin=(0.0, 0.0, 0.0), quads: bool = False):
    """An axis-aligned closed cube facing outward: 12 triangles, or 6 quads with ``quads=True``."""
    o = np.asarray(origin, float)
    points = o + size * np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    quads_list = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    if quads:
        return points, quads_list
    return points, [t for q in quads_list for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])]


def combined(*meshes):
    """Several meshes in one (faces renumbered)."""
    points, faces = [], []
    for p, f in meshes:
        offset = sum(len(x) for x in points)
        points.append(np.asarray(p, float))
        faces += [[i + offset for i in face] for face in f]
    return np.vstack(points), faces


def triangles_of(faces) -> np.ndarray:
    """Fan triangulation of the faces (what a reader should produce, up to order)."""
    return np.array([[f[0], f[i], f[i + 1]] for f in faces for i in range(1, len(f) - 1)], dtype=np.int64)


# ----------------------------------------------------------------------------------------------------------------
# Writers
# ----------------------------------------------------------------------------------------------------------------
def write_stl(path: Path, points, faces, *, binary: bool = True) -> Path:
    tris = np.asarray(points, float)[triangles_of(faces)]
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)
    if binary:
        records = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
        records["n"], records["v"] = normals, tris
        path.write_bytes(b"binary stl made by the voxelscope tests".ljust(80, b" ")
                         + struct.pack("<I", len(tris)) + records.tobytes())
    else:
        lines = ["solid test"]
        for n, t in zip(normals, tris):
            lines += [f"  facet normal {n[0]:.9g} {n[1]:.9g} {n[2]:.9g}", "    outer loop"]
            lines += [f"      vertex {v[0]:.9g} {v[1]:.9g} {v[2]:.9g}" for v in t]
            lines += ["    endloop", "  endfacet"]
        lines.append("endsolid test")
        path.write_text("\n".join(lines) + "\n")
    return path


def write_obj(path: Path, points, faces) -> Path:
    lines = ["# made by the voxelscope tests"] + [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in points]
    lines += ["f " + " ".join(str(i + 1) for i in face) for face in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_off(path: Path, points, faces) -> Path:
    lines = ["OFF", "# made by the voxelscope tests", f"{len(points)} {len(faces)} 0"]
    lines += [f"{x:.9g} {y:.9g} {z:.9g}" for x, y, z in points]
    lines += [f"{len(face)} " + " ".join(map(str, face)) for face in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_ply(path: Path, points, faces, *, binary: bool = True) -> Path:
    header = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", "comment voxelscope tests",
              f"element vertex {len(points)}", "property float x", "property float y", "property float z",
              f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    head = ("\n".join(header) + "\n").encode()
    if binary:
        body = np.asarray(points, "<f4").tobytes()
        body += b"".join(struct.pack("<B", len(f)) + np.asarray(f, "<i4").tobytes() for f in faces)
    else:
        rows = [f"{x:.9g} {y:.9g} {z:.9g}" for x, y, z in points] + [f"{len(f)} " + " ".join(map(str, f)) for f in faces]
        body = ("\n".join(rows) + "\n").encode()
    path.write_bytes(head + body)
    return path


def write_vtp(path: Path, points, faces, *, compressed: bool = True) -> Path:
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    polydata = vtkPolyData()
    vtk_points = vtkPoints()
    vtk_points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    polydata.SetPoints(vtk_points)
    cells = vtkCellArray()
    for face in faces:
        cells.InsertNextCell(len(face), [int(i) for i in face])
    polydata.SetPolys(cells)
    writer = vtkXMLPolyDataWriter()
    writer.SetInputData(polydata)
    writer.SetFileName(str(path))
    if compressed:
        writer.SetCompressorTypeToZLib()
    else:
        writer.SetCompressorTypeToNone()
    writer.Write()
    return path


WRITERS = {
    "stl": lambda p, pts, f: write_stl(p, pts, f, binary=True),
    "ascii.stl": lambda p, pts, f: write_stl(p, pts, f, binary=False),
    "obj": write_obj,
    "ply": lambda p, pts, f: write_ply(p, pts, f, binary=True),
    "ascii.ply": lambda p, pts, f: write_ply(p, pts, f, binary=False),
    "vtp": write_vtp,
    "off": write_off,
}


def write_mesh(folder: Path, name: str, kind: str, points, faces, *, gz: bool = False) -> Path:
    """Write ``(points, faces)`` as ``kind`` (a key of :data:`WRITERS`) into ``folder``; optionally gzip it."""
    suffix = "." + kind.split(".")[-1]
    path = folder / f"{name}-{kind.replace('.', '-')}{suffix}"
    WRITERS[kind](path, np.asarray(points, float), faces)
    if gz:
        zipped = path.with_name(path.name + ".gz")
        zipped.write_bytes(gzip.compress(path.read_bytes()))
        path.unlink()
        return zipped
    return path
