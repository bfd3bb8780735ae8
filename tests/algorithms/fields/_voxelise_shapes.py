"""Closed meshes made in code for the voxelisation tests (outward-facing triangles, shared vertex indices), and the
real meshes of the shared data folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

MESHES = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "meshes"


def box(low, high):
    """An axis-aligned box, 8 points, 12 triangles, facing out."""
    (x0, y0, z0), (x1, y1, z1) = low, high
    points = np.array([[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)], dtype=np.float64)
    # corners: index = x + 2 y + 4 z
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    triangles = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return points, np.array(triangles, dtype=np.int64)


def octahedron(centre, radius):
    """The octahedron ``|x - cx| + |y - cy| + |z - cz| <= radius``, facing out."""
    c = np.asarray(centre, dtype=np.float64)
    points = np.array([c + radius * np.asarray(d) for d in
                       ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))])
    triangles = []
    for x in (0, 1):
        for y in (2, 3):
            for z in (4, 5):
                sx, sy, sz = (1 if x == 0 else -1), (1 if y == 2 else -1), (1 if z == 4 else -1)
                triangles.append((x, y, z) if sx * sy * sz > 0 else (x, z, y))
    return points, np.array(triangles, dtype=np.int64)


def torus(ring, tube, *, around=512, across=256, centre=(0.0, 0.0, 0.0)):
    """A torus around z (ring radius, tube radius in mm), ``around x across`` quads, closed, facing out."""
    u = 2 * np.pi * np.arange(around) / around
    v = 2 * np.pi * np.arange(across) / across
    uu, vv = np.meshgrid(u, v, indexing="ij")
    radius = ring + tube * np.cos(vv)
    points = np.stack([radius * np.cos(uu), radius * np.sin(uu), tube * np.sin(vv)], axis=-1).reshape(-1, 3)
    return points + np.asarray(centre), _wrapped_quads(around, across)


def sphere(radius, *, around=512, across=256, centre=(0.0, 0.0, 0.0)):
    """A UV sphere (poles as single points), closed, facing out."""
    theta = np.pi * np.arange(1, across) / across  # latitude rings, poles excluded
    phi = 2 * np.pi * np.arange(around) / around
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    ring_points = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1).reshape(-1, 3)
    points = np.concatenate([[[0, 0, 1]], ring_points, [[0, 0, -1]]]) * radius + np.asarray(centre)
    rings = across - 1
    index = 1 + np.arange(rings * around).reshape(rings, around)
    nxt = np.roll(index, -1, axis=1)
    triangles = [np.stack([np.zeros(around, int), index[0], nxt[0]], 1)]
    for r in range(rings - 1):
        a, b, c, d = index[r], nxt[r], nxt[r + 1], index[r + 1]
        triangles += [np.stack([a, d, c], 1), np.stack([a, c, b], 1)]
    south = len(points) - 1
    triangles.append(np.stack([np.full(around, south), nxt[-1], index[-1]], 1))
    return points, np.concatenate(triangles).astype(np.int64)


def _wrapped_quads(nu, nv):
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])


def joined(*meshes):
    """Several meshes as one (indices shifted)."""
    points, triangles, offset = [], [], 0
    for p, t in meshes:
        points.append(p)
        triangles.append(t + offset)
        offset += len(p)
    return np.concatenate(points), np.concatenate(triangles)


def flipped(mesh):
    points, triangles = mesh
    return points, triangles[:, ::-1].copy()


def real_mesh(name: str):
    """Points and triangles of ``name`` in the shared data folder (skips the test when the folder is absent)."""
    from app.io.meshes import load_mesh

    path = MESHES / name
    if not path.exists():
        pytest.skip(f"the shared test meshes are not here ({MESHES})")
    mesh = load_mesh(path)
    return mesh.points, mesh.triangles, mesh.polydata


def rotation(axis, degrees) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    axis /= np.linalg.norm(axis)
    angle = np.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
