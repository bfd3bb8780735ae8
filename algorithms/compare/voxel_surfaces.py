"""Checks and accounting for voxel-face surfaces: exact face coverage, and memory as source 000 counts it.

(a) Coverage. :func:`face_set` maps every triangle of a surface (indexed triangles, quads, triangle strips under
VTK's alternating-winding rule) back to the voxel face it lies on and checks that each face is covered exactly once
by exactly two triangles (the two halves of the quad along either diagonal, wound the same way) and that nothing
else is drawn: degenerate strip triangles, triangles off the voxel-corner lattice, half-covered, overdrawn or
mixed-winding faces are all counted as defects, never skipped. :func:`same_faces` compares two surfaces
order-independently. This is the equivalence argument of source 000 (section 7) made executable.

(b) Memory, as source 000 counts it (section 9.1): bytes of vertex positions (3 x float32 per vertex) plus bytes
of indices, reported for 16- and 32-bit indices, with the number of strips (draw calls in the source's Direct3D
set-up) and vertices. See :class:`MemoryUsage`, :func:`memory_usage`, :func:`stripper_memory`.

VTK's own paths (the reference face set of ``vtkThreshold`` + ``vtkDataSetSurfaceFilter``, ``vtkStripper`` on the
baseline triangles) are in :mod:`algorithms.references.vtk_surfaces`.

Surfaces are recognised by the mesh types of :mod:`algorithms.common.mesh`: a
:class:`~algorithms.common.mesh.TriangleMesh` (the baseline's voxel faces), a
:class:`~algorithms.common.mesh.TriangleStrips` (the tower's strips), or an object with ``faces`` (a mesh) and
``strips`` (the hybrid); each carries the ``spacing`` and ``origin`` of its voxel grid.

Face keys
---------
A face is the row ``(hx, hy, hz, axis, side)`` (int64): its centre in half-voxel units relative to ``origin``
(``2 * (centre - origin) / spacing``; odd along the face's axis, even across it), the axis (0, 1, 2 = x, y, z) and
the outward side (-1 or +1). Face sets are sorted lexicographically. The ``+x`` face of voxel ``(i, j, k)`` is
``(2i + 1, 2j, 2k, 0, +1)``.

References
----------
Source 000 (Dutch BSc thesis on voxel models as triangle strips, see docs/references.md), sections 7
(equivalence) and 9.1 (memory).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ..common.mesh import TriangleMesh, TriangleStrips, csr_ranks
from ..common.validation import validated_geometry
from ..common.vtk_bridge import cell_arrays

#: Largest distance (in voxels) of a vertex from the voxel-corner lattice still taken as on it.
LATTICE_TOLERANCE = 1e-3

DEFECTS = (
    "degenerate triangles",
    "off-grid triangles",
    "half-covered faces",
    "overdrawn faces",
    "faces with overlapping halves",
    "faces with mixed winding",
    "other cells",
)


# ----------------------------------------------------------------------------------------------------------------
# (a) coverage
# ----------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FaceSet:
    """The voxel faces a surface draws, and everything it draws that is not a clean face.

    Attributes
    ----------
    faces : ndarray, shape (F, 5), int64
        Sorted face keys ``(hx, hy, hz, axis, side)`` of the faces covered by exactly two complementary,
        equally wound triangles.
    n_triangles : int
        Triangles examined (strips decomposed).
    defects : dict[str, int]
        Count per kind in :data:`DEFECTS`; all zero for a clean surface.
    """

    faces: np.ndarray
    n_triangles: int
    defects: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not any(self.defects.values())

    def __len__(self) -> int:
        return len(self.faces)


def strip_triangles(offsets, connectivity) -> np.ndarray:
    """The triangles ``(T, 3)`` of CSR triangle strips under VTK's rule (odd triangles swap their first two ids).

    Strip ``s`` is ``connectivity[offsets[s]:offsets[s + 1]]``; a strip of ``n >= 3`` ids gives ``n - 2``
    triangles, shorter ones none.
    """
    offsets = np.asarray(offsets, dtype=np.int64)
    connectivity = np.asarray(connectivity, dtype=np.int64)
    lengths = np.diff(offsets)
    counts = np.maximum(lengths - 2, 0)
    first = np.repeat(offsets[:-1], counts)
    rank = csr_ranks(counts)
    position = first + rank
    odd = (rank % 2).astype(bool)
    a, b, c = connectivity[position], connectivity[position + 1], connectivity[position + 2]
    return np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)


def face_set(
    points,
    triangles=None,
    strips=None,
    quads=None,
    *,
    spacing=(1.0, 1.0, 1.0),
    origin=(0.0, 0.0, 0.0),
) -> FaceSet:
    """The set of voxel faces covered by a surface, with every coverage defect counted.

    Parameters
    ----------
    points : ndarray, shape (P, 3)
        Vertex positions in the volume frame (mm, ``(x, y, z)``).
    triangles : ndarray, shape (T, 3), optional
        Indexed triangles.
    strips : (offsets, connectivity), optional
        Triangle strips in CSR form (``offsets`` of length ``S + 1``, point ids); decomposed with
        :func:`strip_triangles`.
    quads : ndarray, shape (Q, 4), optional
        Quads, each taken as the triangles ``(0, 1, 2)`` and ``(0, 2, 3)``.
    spacing, origin : (x, y, z)
        The voxel lattice: voxel ``(i, j, k)`` is centred at ``origin + spacing * (i, j, k)``.

    Returns
    -------
    FaceSet

    Raises
    ------
    ValueError
        If ``points`` is not ``(P, 3)``, if an index array has the wrong shape or an id is out of range, or if
        spacing/origin are invalid.

    Notes
    -----
    A triangle counts as half of a face when its vertices lie within :data:`LATTICE_TOLERANCE` voxels of
    distinct voxel corners, share one coordinate (the face's plane) and span exactly one voxel in the two others.
    Two triangles cover a face when they are the complementary halves of its quad (the corners they leave out are
    opposite, so either diagonal is allowed) and their normals agree; that normal gives the face's side.
    """
    spacing_t, origin_t = validated_geometry(spacing, origin)
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be an (n, 3) array, got shape {points.shape}")
    parts = []
    if triangles is not None:
        parts.append(_ids(triangles, 3, "triangles"))
    if quads is not None:
        quads = _ids(quads, 4, "quads")
        parts.append(quads[:, [[0, 1, 2], [0, 2, 3]]].reshape(-1, 3))
    if strips is not None:
        offsets, connectivity = strips
        parts.append(strip_triangles(offsets, connectivity))
    ids = np.concatenate(parts) if parts else np.empty((0, 3), dtype=np.int64)
    if len(ids) and (ids.min() < 0 or ids.max() >= len(points)):
        raise ValueError(f"point ids must lie in [0, {len(points)}), got [{ids.min()}, {ids.max()}]")
    defects = dict.fromkeys(DEFECTS, 0)

    lattice = (points - np.asarray(origin_t)) / np.asarray(spacing_t) + 0.5  # voxel-corner coordinates
    corner = np.rint(lattice)
    on_lattice = np.all(np.abs(lattice - corner) <= LATTICE_TOLERANCE, axis=1)
    corner = corner.astype(np.int64)

    tri = corner[ids]  # (T, 3 vertices, 3 coords)
    tri_on_lattice = on_lattice[ids].all(axis=1)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    repeated_id = (ids[:, 0] == ids[:, 1]) | (ids[:, 1] == ids[:, 2]) | (ids[:, 0] == ids[:, 2])
    degenerate = repeated_id | (tri_on_lattice & ~normal.any(axis=1))  # zero area
    shared = (tri[:, 0] == tri[:, 1]) & (tri[:, 0] == tri[:, 2])  # (T, 3): the coordinates all three share
    extent = tri.max(axis=1) - tri.min(axis=1)
    half_face = tri_on_lattice & ~degenerate & (shared.sum(axis=1) == 1) & (extent.sum(axis=1) == 2)
    half_face &= extent.max(axis=1) == 1  # one coordinate shared, one voxel along both others
    defects["degenerate triangles"] = int(degenerate.sum())
    defects["off-grid triangles"] = int((~degenerate & ~half_face).sum())

    tri, normal = tri[half_face], normal[half_face]
    axis = np.argmax(shared[half_face], axis=1)
    rows = np.arange(len(tri))
    low = tri.min(axis=1)

    def local(along: np.ndarray) -> np.ndarray:
        """(T, 3) coordinates of the three vertices along ``along``, relative to the face's low corner (0 or 1)."""
        return np.take_along_axis(tri, along[:, None, None], axis=2)[:, :, 0] - low[rows, along][:, None]

    missing = 6 - (local((axis + 1) % 3) + 2 * local((axis + 2) % 3)).sum(axis=1)  # corner codes 0..3 sum to 6
    side = np.sign(normal[rows, axis])
    centre = 2 * low
    centre[rows, axis] = 2 * tri[rows, 0, axis] - 1
    keys = np.column_stack([centre, axis, side])

    order = np.lexsort((keys[:, 3], keys[:, 2], keys[:, 1], keys[:, 0]))  # group by face, ignoring the side
    keys, missing = keys[order], missing[order]
    new_face = np.ones(len(keys), dtype=bool)
    new_face[1:] = np.any(keys[1:, :4] != keys[:-1, :4], axis=1)
    starts = np.flatnonzero(new_face)
    counts = np.diff(np.append(starts, len(keys)))
    defects["half-covered faces"] = int((counts == 1).sum())
    defects["overdrawn faces"] = int((counts > 2).sum())
    pairs = starts[counts == 2]
    complementary = (missing[pairs] ^ missing[pairs + 1]) == 3
    same_winding = keys[pairs, 4] == keys[pairs + 1, 4]
    defects["faces with overlapping halves"] = int((~complementary).sum())
    defects["faces with mixed winding"] = int((complementary & ~same_winding).sum())
    good = pairs[complementary & same_winding]
    return FaceSet(faces=_sorted_rows(keys[good]), n_triangles=len(ids), defects=defects)


def _ids(array, width: int, name: str) -> np.ndarray:
    array = np.asarray(array)
    if array.ndim != 2 or array.shape[1] != width or (array.size and array.dtype.kind not in "iu"):
        raise ValueError(f"{name} must be an integer (n, {width}) array, got shape {array.shape} ({array.dtype})")
    return array.astype(np.int64, copy=False)


def _sorted_rows(rows: np.ndarray) -> np.ndarray:
    rows = np.asarray(rows, dtype=np.int64).reshape(-1, 5)
    return rows[np.lexsort(rows.T[::-1])]


def voxel_face_keys(voxel_ijk, directions) -> np.ndarray:
    """Sorted face keys ``(F, 5)`` of faces given by voxel ``(i, j, k)`` and direction code (``-x, +x, ..., +z``)."""
    voxel_ijk = np.asarray(voxel_ijk, dtype=np.int64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.int64)
    axis = directions // 2
    side = np.where(directions % 2 == 1, 1, -1)
    centre = 2 * voxel_ijk
    centre[np.arange(len(axis)), axis] += side
    return _sorted_rows(np.column_stack([centre, axis, side]))


def _surface_parts(surface):
    """``(mesh, strips)`` of one of our voxel-surface results (either may be None), or None for anything else.

    A voxel-surface result carries the ``spacing`` and ``origin`` of its voxel grid.
    """
    if not (hasattr(surface, "spacing") and hasattr(surface, "origin")):
        return None
    if isinstance(surface, TriangleStrips):
        return None, surface
    if isinstance(surface, TriangleMesh):
        return surface, None
    faces, strips = getattr(surface, "faces", None), getattr(surface, "strips", None)
    if isinstance(faces, TriangleMesh) and isinstance(strips, TriangleStrips):
        return faces, strips
    return None


def surface_face_set(surface, *, spacing=None, origin=None) -> FaceSet:
    """:func:`face_set` of a voxel-surface result (voxel faces, tower strips, hybrid) or a ``vtkPolyData``.

    Our results carry their spacing and origin; for a ``vtkPolyData`` pass them (default 1 mm and 0). Polygons
    of a ``vtkPolyData`` may be triangles or quads; vertices, lines and larger polygons count as "other cells".
    """
    parts = _surface_parts(surface)
    if parts is not None:
        if spacing is not None or origin is not None:
            raise ValueError("the surface carries its own spacing and origin")
        mesh, strips = parts
        first = 0 if mesh is None else mesh.n_points
        points = [part.points for part in parts if part is not None]
        return face_set(
            np.concatenate(points) if len(points) > 1 else points[0],
            None if mesh is None else mesh.triangles,
            strips=None if strips is None else (strips.offsets, np.arange(first, first + strips.n_vertices)),
            spacing=surface.spacing,
            origin=surface.origin,
        )
    if isinstance(surface, vtkPolyData):
        spacing = (1.0, 1.0, 1.0) if spacing is None else spacing
        origin = (0.0, 0.0, 0.0) if origin is None else origin
        return _polydata_face_set(surface, spacing=spacing, origin=origin)
    raise ValueError(f"cannot take the face set of a {type(surface).__name__}")


def _polydata_face_set(polydata: vtkPolyData, *, spacing, origin) -> FaceSet:
    points = polydata.GetPoints()
    points = numpy_support.vtk_to_numpy(points.GetData()) if points is not None else np.empty((0, 3))
    offsets, connectivity = cell_arrays(polydata.GetPolys())
    sizes = np.diff(offsets)
    starts = offsets[:-1]
    triangles = connectivity[starts[sizes == 3][:, None] + np.arange(3)]
    quads = connectivity[starts[sizes == 4][:, None] + np.arange(4)]
    result = face_set(
        points,
        triangles,
        strips=cell_arrays(polydata.GetStrips()),
        quads=quads,
        spacing=spacing,
        origin=origin,
    )
    other = int(((sizes != 3) & (sizes != 4)).sum())
    other += polydata.GetVerts().GetNumberOfCells() + polydata.GetLines().GetNumberOfCells()
    return replace(result, defects={**result.defects, "other cells": other})


def describe_face(key) -> str:
    """``"voxel (i, j, k) +x"`` for a face key row."""
    hx, hy, hz, axis, side = (int(v) for v in key)
    centre = [hx, hy, hz]
    centre[axis] -= side
    i, j, k = (c // 2 for c in centre)
    return f"voxel ({i}, {j}, {k}) {'+' if side > 0 else '-'}{'xyz'[axis]}"


def same_faces(a, b, *, examples: int = 5) -> tuple[bool, str]:
    """Whether two surfaces draw exactly the same voxel faces (order-independent), and a report saying how not.

    ``a`` and ``b`` are :class:`FaceSet` or anything :func:`surface_face_set` accepts. Equal means: neither has
    a defect, and the sorted face keys (position, axis and outward side) are identical.
    """
    a = a if isinstance(a, FaceSet) else surface_face_set(a)
    b = b if isinstance(b, FaceSet) else surface_face_set(b)
    lines = []
    for name, s in (("first", a), ("second", b)):
        bad = {kind: n for kind, n in s.defects.items() if n}
        if bad:
            lines.append(f"{name} surface has defects: " + ", ".join(f"{n} {kind}" for kind, n in bad.items()))
    view = np.dtype([("", np.int64)] * 5)
    set_a = np.ascontiguousarray(a.faces).view(view).ravel()
    set_b = np.ascontiguousarray(b.faces).view(view).ravel()
    only_a = np.setdiff1d(set_a, set_b)
    only_b = np.setdiff1d(set_b, set_a)
    for name, only in (("first", only_a), ("second", only_b)):
        if len(only):
            shown = ", ".join(describe_face(tuple(row)) for row in only[:examples])
            lines.append(f"{len(only)} faces only in the {name} surface, e.g. {shown}")
    equal = not lines
    summary = f"{len(a)} and {len(b)} faces" + ("; identical" if equal else "")
    return equal, "; ".join([summary] + lines)


# ----------------------------------------------------------------------------------------------------------------
# (b) memory as source 000 counts it
# ----------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MemoryUsage:
    """What a representation would put in GPU buffers (source 000, section 9.1).

    Attributes
    ----------
    representation : str
    vertices : int
        Vertices stored, each 3 x float32 = 12 bytes.
    indices : int
        Indices stored (16 or 32 bits each).
    strips : int
        Triangle strips, each one draw call in the source's Direct3D set-up.
    draw_calls : int
        ``strips`` plus one for the indexed triangle list, if any.
    triangles : int
        Triangles drawn.

    Notes
    -----
    16-bit indices address at most 65,536 vertices per draw; the 16-bit figures assume the geometry is cut into
    batches that small, as the source's byte counts do, and ignore the extra draw calls and vertices that costs.

    :attr:`vtk_upload_bytes` is what VTK's OpenGL2 mapper actually puts in GPU buffers for the same polydata:
    every point once as float32 and three 32-bit indices per triangle, strips included, because it decomposes
    strips on the CPU into the same triangle index buffer as polygons
    (``vtkOpenGLIndexBufferObject::AppendStripIndexBuffer``) and draws each primitive type with one call.
    """

    representation: str
    vertices: int
    indices: int
    strips: int
    draw_calls: int
    triangles: int

    @property
    def vertex_bytes(self) -> int:
        return 12 * self.vertices

    def index_bytes(self, bits: int = 32) -> int:
        if bits not in (16, 32):
            raise ValueError(f"index width is 16 or 32 bits, got {bits}")
        return self.indices * bits // 8

    def total_bytes(self, bits: int = 32) -> int:
        return self.vertex_bytes + self.index_bytes(bits)

    @property
    def vtk_upload_bytes(self) -> int:
        return 12 * self.vertices + 12 * self.triangles

    def as_row(self) -> dict:
        return {
            "representation": self.representation,
            "vertices": self.vertices,
            "indices": self.indices,
            "strips": self.strips,
            "draw_calls": self.draw_calls,
            "triangles": self.triangles,
            "vertex_bytes": self.vertex_bytes,
            "bytes_16": self.total_bytes(16),
            "bytes_32": self.total_bytes(32),
            "vtk_upload_bytes": self.vtk_upload_bytes,
        }


def memory_usage(surface) -> MemoryUsage:
    """Memory of a voxel-surface result: voxel faces ("baseline", a :class:`~algorithms.common.mesh.TriangleMesh`),
    tower strips ("tower", a :class:`~algorithms.common.mesh.TriangleStrips`) or the hybrid of both ("hybrid")."""
    parts = _surface_parts(surface)
    if parts is None:
        raise ValueError(f"no memory accounting for a {type(surface).__name__}")
    mesh, strips = parts
    if strips is None:
        n_triangles = mesh.n_triangles
        return MemoryUsage("baseline", mesh.n_points, 3 * n_triangles, 0, 1 if n_triangles else 0, n_triangles)
    if mesh is None:
        return MemoryUsage("tower", strips.n_vertices, 0, strips.n_strips, strips.n_strips, strips.n_triangles)
    return MemoryUsage(
        "hybrid",
        mesh.n_points + strips.n_vertices,
        mesh.triangles.size,
        strips.n_strips,
        strips.n_strips + (1 if mesh.n_triangles else 0),
        mesh.n_triangles + strips.n_triangles,
    )


def polydata_memory(polydata: vtkPolyData) -> MemoryUsage:
    """:func:`memory_usage` of a voxel surface as our voxel-surface filters output it: indexed triangles over their
    own points (voxel faces, "baseline"), strips whose vertices are stored in strip order (tower), or both over one
    point list, triangle points first (hybrid)."""
    poly_offsets, poly_ids = cell_arrays(polydata.GetPolys())
    strip_offsets, _ = cell_arrays(polydata.GetStrips())
    n_triangles = len(poly_offsets) - 1
    n_strips = len(strip_offsets) - 1
    strip_vertices = int(strip_offsets[-1])
    strip_triangles = strip_vertices - 2 * n_strips
    triangle_points = int(poly_ids.max()) + 1 if poly_ids.size else 0
    if n_strips == 0:
        return MemoryUsage("baseline", triangle_points, 3 * n_triangles, 0, 1 if n_triangles else 0, n_triangles)
    if n_triangles == 0:
        return MemoryUsage("tower", strip_vertices, 0, n_strips, n_strips, strip_triangles)
    return MemoryUsage("hybrid", triangle_points + strip_vertices, 3 * n_triangles, n_strips, n_strips + 1,
                       n_triangles + strip_triangles)


def stripper_memory(polydata: vtkPolyData) -> tuple[MemoryUsage, MemoryUsage]:
    """Memory of ``vtkStripper`` output, counted both ways: ``(indexed, de-indexed)``.

    vtkStripper's strips are lists of ids into a shared point list, and triangles it could not join stay as
    polygons. Indexed ("vtkStripper"): every shared point once, plus one index per strip entry and three per
    leftover triangle. De-indexed ("vtkStripper-deindexed"): every strip entry stored as a vertex in strip order
    (the tower algorithm's storage) and three vertices per leftover triangle, no indices.
    """
    offsets, _ = cell_arrays(polydata.GetStrips())
    lengths = np.diff(offsets)
    n_strips = len(lengths)
    strip_entries = int(lengths.sum())
    n_polys = polydata.GetPolys().GetNumberOfCells()
    triangles = strip_entries - 2 * n_strips + n_polys
    draw_calls = n_strips + (1 if n_polys else 0)
    indexed = MemoryUsage(
        "vtkStripper", polydata.GetNumberOfPoints(), strip_entries + 3 * n_polys, n_strips, draw_calls, triangles
    )
    deindexed = MemoryUsage("vtkStripper-deindexed", strip_entries + 3 * n_polys, 0, n_strips, draw_calls, triangles)
    return indexed, deindexed


__all__ = [
    "DEFECTS",
    "LATTICE_TOLERANCE",
    "FaceSet",
    "MemoryUsage",
    "describe_face",
    "face_set",
    "memory_usage",
    "same_faces",
    "strip_triangles",
    "stripper_memory",
    "surface_face_set",
    "voxel_face_keys",
]
