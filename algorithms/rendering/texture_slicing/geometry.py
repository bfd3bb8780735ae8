"""Slice geometry of texture slicing: view-aligned plane-box sections and the axis-aligned stacks.

See :mod:`algorithms.rendering.texture_slicing` for the method; everything here is in the volume frame (mm,
``(x, y, z)``), polygons back to front, counter-clockwise as seen from the camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from ...common.camera import Camera, checked_camera
from ...common.mesh import csr_ranks
from ...common.validation import validated_spacing
from ...common.vtk_bridge import polydata_from_arrays


#: Slice stacks: planes perpendicular to the view direction, or the axis-aligned stack through the voxel layers.
MODES = ("view", "axis")
#: A plane cuts at most six of the twelve box edges.
MAX_POLYGON_VERTICES = 6
#: Corner ``c`` of a box has bit 0, 1, 2 of ``c`` set where it takes the maximum of x, y, z.
_CORNER_BITS = np.array([[(c >> axis) & 1 for axis in range(3)] for c in range(8)], dtype=np.float64)
#: The twelve box edges as pairs of corner indices (the corners differ in exactly one bit).
BOX_EDGES = np.array([(c, c | (1 << axis)) for axis in range(3) for c in range(8) if not c & (1 << axis)],
                     dtype=np.int64)
#: Relative tolerance (of the box diagonal) below which two cut points are the same vertex.
MERGE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SlicePolygons:
    """A stack of planar slice polygons through a box, in back-to-front order.

    Attributes
    ----------
    vertices : ndarray, shape (n, 6, 3), float64
        Polygon vertices in the volume frame (mm, ``(x, y, z)``), counter-clockwise as seen from the camera;
        rows ``counts[s]`` and beyond are NaN. Slice 0 is the farthest from the camera.
    counts : ndarray, shape (n,), int64
        Number of vertices of each polygon (3 to 6).
    offsets : ndarray, shape (n,), float64
        Plane of slice ``s``: ``normal . x = offsets[s]`` (mm); decreasing with ``s`` (back to front).
    normal : ndarray, shape (3,)
        Unit normal of every slice, pointing away from the camera (``normal . f > 0``).
    u_axis, v_axis : ndarray, shape (3,)
        Orthonormal in-plane axes with ``u x v = -normal``: angles measured from ``u`` towards ``v`` run
        counter-clockwise as seen from the camera. For view-aligned slices they are the camera's right and up.
    slice_distance : float
        Distance between neighbouring planes along ``normal`` (mm).
    path_step : float
        Distance between neighbouring planes along the central view direction ``f``,
        ``slice_distance / |normal . f|`` (mm): the sample distance along a ray the opacity is corrected for.
    box_min, box_max : ndarray, shape (3,)
        The sliced box (mm).
    axis : int or None
        The axis (0 = x, 1 = y, 2 = z) of an axis-aligned stack; None for view-aligned slices.
    """

    vertices: np.ndarray
    counts: np.ndarray
    offsets: np.ndarray
    normal: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    slice_distance: float
    path_step: float
    box_min: np.ndarray
    box_max: np.ndarray
    axis: int | None = None

    def __len__(self) -> int:
        return len(self.counts)

    @property
    def texture_coordinates(self) -> np.ndarray:
        """3D texture coordinates of the vertices, ``(n, 6, 3)``: positions normalised to the box, in [0, 1]."""
        return (self.vertices - self.box_min) / (self.box_max - self.box_min)

    def polygon(self, index: int) -> np.ndarray:
        """The ``(counts[index], 3)`` vertices of slice ``index``."""
        return self.vertices[index, : self.counts[index]]

    def areas(self) -> np.ndarray:
        """Area of each polygon in mm^2, ``(n,)`` (shoelace formula in the plane frame; positive for CCW)."""
        u = self.vertices @ self.u_axis
        v = self.vertices @ self.v_axis
        valid = np.arange(MAX_POLYGON_VERTICES)[None, :] < self.counts[:, None]
        following = (np.arange(MAX_POLYGON_VERTICES)[None, :] + 1) % self.counts[:, None]
        u_next = np.take_along_axis(u, following, axis=1)
        v_next = np.take_along_axis(v, following, axis=1)
        return 0.5 * np.where(valid, u * v_next - u_next * v, 0.0).sum(axis=1)

    def fan_triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every polygon as a triangle fan, in slice order.

        Returns
        -------
        points : ndarray, shape (p, 3)
            The valid vertices of all slices, slice after slice (``p = counts.sum()``).
        triangles : ndarray, shape (t, 3), int64
            Fan triangles ``(0, i, i + 1)`` of each polygon as indices into ``points`` (``t = (counts - 2).sum()``),
            counter-clockwise as seen from the camera, back-to-front slice order.
        slice_index : ndarray, shape (t,), int64
            The slice each triangle belongs to.
        """
        valid = np.arange(MAX_POLYGON_VERTICES)[None, :] < self.counts[:, None]
        points = self.vertices[valid]
        first = np.cumsum(self.counts) - self.counts
        fans = self.counts - 2
        slice_index = np.repeat(np.arange(len(self)), fans)
        within = csr_ranks(fans)  # i - 1 of fan triangle (0, i, i + 1)
        start = first[slice_index]
        triangles = np.stack([start, start + within + 1, start + within + 2], axis=1).astype(np.int64)
        return points, triangles, slice_index


def _validated_box(box_min, box_max) -> tuple[np.ndarray, np.ndarray]:
    low = np.asarray(box_min, dtype=np.float64).reshape(-1)
    high = np.asarray(box_max, dtype=np.float64).reshape(-1)
    if low.shape != (3,) or high.shape != (3,) or not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        raise ValueError(f"box_min and box_max must be finite 3-vectors (mm), got {box_min!r} and {box_max!r}")
    if not np.all(high > low):
        raise ValueError(f"the box must have a positive extent along every axis, got {low.tolist()} to {high.tolist()}")
    return low, high


def _box_corners(box_min: np.ndarray, box_max: np.ndarray) -> np.ndarray:
    return box_min + _CORNER_BITS * (box_max - box_min)


def _order_polygons(points: np.ndarray, valid: np.ndarray, u_axis, v_axis, tolerance: float):
    """Sort each slice's cut points by angle around their centroid, merge coincident ones, pad to six with NaN.

    ``points`` is ``(n, m, 3)`` with ``valid`` ``(n, m)``; returns ``(vertices (n, 6, 3), counts (n,))``. The
    centroid of the cut points (duplicates included) has positive weight on every vertex, so it lies strictly
    inside the polygon and the angles order the vertices along its boundary, counter-clockwise from ``u`` to
    ``v``. Coincident points (a plane through a corner cuts up to three edges there) get equal angles, so they
    end up next to each other and are merged.
    """
    n = len(points)
    centroid = np.where(valid[..., None], points, 0.0).sum(axis=1) / np.maximum(valid.sum(axis=1), 1)[:, None]
    relative = points - centroid[:, None, :]
    angle = np.arctan2(relative @ v_axis, relative @ u_axis)
    angle = np.where(valid, angle, np.inf)
    order = np.argsort(angle, axis=1, kind="stable")
    points = np.take_along_axis(points, order[..., None], axis=1)
    keep = np.take_along_axis(valid, order, axis=1)
    with np.errstate(invalid="ignore"):
        gap = np.linalg.norm(points[:, 1:] - points[:, :-1], axis=2)
        keep[:, 1:] &= gap > tolerance
    compact = np.argsort(~keep, axis=1, kind="stable")
    points = np.take_along_axis(points, compact[..., None], axis=1)
    counts = keep.sum(axis=1)
    # Close the cycle: the last vertex may coincide with the first (equal angles at the +-pi seam).
    last = points[np.arange(n), np.maximum(counts - 1, 0)]
    counts = counts - ((counts > 1) & (np.linalg.norm(last - points[:, 0], axis=1) <= tolerance))
    if np.any(counts > MAX_POLYGON_VERTICES):
        raise RuntimeError("a plane-box intersection produced more than six distinct vertices")
    width = max(points.shape[1], MAX_POLYGON_VERTICES)
    vertices = np.full((n, width, 3), np.nan)
    vertices[:, : points.shape[1]] = points
    vertices[np.arange(width)[None, :] >= counts[:, None]] = np.nan
    return vertices[:, :MAX_POLYGON_VERTICES], counts.astype(np.int64)


def slice_polygons(camera: Camera, box_min, box_max, count: int) -> SlicePolygons:
    """View-aligned slices: ``count`` plane-box intersections perpendicular to the view direction.

    Parameters
    ----------
    camera : Camera
        The camera in the box's frame; its direction of projection ``f`` is the planes' normal.
    box_min, box_max : 3 floats
        Opposite corners of the axis-aligned box (mm, ``(x, y, z)``), ``box_max > box_min`` on every axis.
    count : int
        Number of slices (>= 1). The depth range between the nearest and the farthest box corner is cut into
        ``count`` equal slabs; each plane lies in the middle of its slab.

    Returns
    -------
    SlicePolygons
        Polygons of 3 to 6 vertices, back to front (slice 0 farthest), counter-clockwise as seen from the camera
        (``u_axis``/``v_axis`` are the camera's right/up), ``slice_distance = path_step = depth / count``.

    Raises
    ------
    ValueError
        If ``count`` is not a positive integer or the box is not a finite box of positive extent.

    Notes
    -----
    The cut point of edge ``(a, b)`` with signed corner distances ``d_a``, ``d_b`` to the plane is
    ``c_a + d_a / (d_a - d_b) (c_b - c_a)``; an edge is cut when its corners lie on different sides, a corner on
    the plane counting as beyond it, so a plane through a corner yields that corner exactly, once per edge to the
    near side, and the copies are merged. Planes lie strictly between the nearest and farthest corner, so every
    section has positive area. Source 001, technique 3; source 002, fig. 2.6.
    """
    camera = checked_camera(camera)
    low, high = _validated_box(box_min, box_max)
    if int(count) != count or count < 1:
        raise ValueError(f"count must be a positive integer, got {count!r}")
    count = int(count)
    right, up, forward = camera.basis()
    corners = _box_corners(low, high)
    heights = corners @ forward
    near, far = float(heights.min()), float(heights.max())
    distance = (far - near) / count
    offsets = far - (np.arange(count) + 0.5) * distance

    signed = heights[None, :] - offsets[:, None]  # (n, 8): corner distance beyond the plane (< 0: nearer)
    a, b = BOX_EDGES[:, 0], BOX_EDGES[:, 1]
    da, db = signed[:, a], signed[:, b]
    cut = (da >= 0) != (db >= 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(cut, da / (da - db), np.nan)
    points = corners[a] + t[..., None] * (corners[b] - corners[a])
    points = np.where((t == 1.0)[..., None], corners[b], points)  # exact corner, so duplicates merge exactly
    tolerance = MERGE_TOLERANCE * float(np.linalg.norm(high - low))
    vertices, counts = _order_polygons(points, cut, right, up, tolerance)
    return SlicePolygons(vertices, counts, offsets, forward, right, up, distance, distance, low, high, None)


def default_slice_count(camera: Camera, box_min, box_max, spacing) -> int:
    """One view-aligned slice per smallest voxel spacing: ``ceil(depth / min(spacing))``.

    ``depth`` is the distance between the planes through the nearest and the farthest box corner along the view
    direction, so the slices end up ``depth / count <= min(spacing)`` mm apart.

    Raises
    ------
    ValueError
        On an invalid box or spacing that is not three positive numbers.
    """
    camera = checked_camera(camera)
    low, high = _validated_box(box_min, box_max)
    return slice_count(camera, low, high, float(validated_spacing(spacing).min()))


def slice_count(camera: Camera, box_min, box_max, slice_distance: float) -> int:
    """``ceil(depth / slice_distance)``: view-aligned slices at most ``slice_distance`` mm apart over the box's
    depth along the view direction (the box as in :func:`slice_polygons`, assumed valid)."""
    low, high = np.asarray(box_min, dtype=np.float64), np.asarray(box_max, dtype=np.float64)
    heights = _box_corners(low, high) @ camera.direction
    return max(1, math.ceil(float(heights.max() - heights.min()) / slice_distance - 1e-9))


def axis_aligned_slices(camera: Camera, box_min, box_max, spacing) -> SlicePolygons:
    """The axis-aligned stack for ``camera``: slices through every layer of voxel centres, back to front.

    Parameters
    ----------
    camera : Camera
        The camera in the box's frame. The stack is the one along the axis of the largest ``|f_axis|`` of its
        view direction ``f`` (the first such axis on a tie), source 002's switching rule.
    box_min, box_max : 3 floats
        The box of voxel centres (mm): ``box_min`` is the first voxel centre.
    spacing : 3 floats
        Voxel size (mm, ``(sx, sy, sz)``). Slices lie at ``box_min[a] + k * spacing[a]`` for every ``k`` inside the
        box along the stack axis ``a``.

    Returns
    -------
    SlicePolygons
        Rectangles (4 vertices) counter-clockwise as seen along ``f``; ``normal = sign(f_a) e_a``,
        ``slice_distance = spacing[a]``, ``path_step = spacing[a] / |f_a|``, ``axis = a``.

    Raises
    ------
    ValueError
        On an invalid box or spacing.
    """
    camera = checked_camera(camera)
    low, high = _validated_box(box_min, box_max)
    sizes = validated_spacing(spacing)
    forward = camera.direction
    axis = int(np.argmax(np.abs(forward)))
    sign = 1.0 if forward[axis] > 0 else -1.0
    layers = int(math.floor((high[axis] - low[axis]) / sizes[axis] + 1e-9)) + 1
    positions = low[axis] + np.arange(layers) * sizes[axis]
    positions = positions[::-1] if sign > 0 else positions  # far layers first
    normal = np.zeros(3)
    normal[axis] = sign
    u_axis = np.zeros(3)
    v_axis = np.zeros(3)
    b, c = (axis + 1) % 3, (axis + 2) % 3
    u_axis[b] = 1.0
    v_axis[c] = -sign  # e_b x e_c = e_a, so u x v = -sign e_a = -normal
    corners = np.zeros((layers, 4, 3))
    corners[:, :, axis] = positions[:, None]
    corners[:, :, b] = np.array([low[b], high[b], high[b], low[b]])
    corners[:, :, c] = np.array([low[c], low[c], high[c], high[c]])
    tolerance = MERGE_TOLERANCE * float(np.linalg.norm(high - low))
    vertices, counts = _order_polygons(corners, np.ones((layers, 4), dtype=bool), u_axis, v_axis, tolerance)
    return SlicePolygons(
        vertices, counts, sign * positions, normal, u_axis, v_axis, float(sizes[axis]),
        float(sizes[axis] / abs(forward[axis])), low, high, axis,
    )


def slices_to_polydata(polygons: SlicePolygons) -> vtkPolyData:
    """``polygons`` as fan triangles (back to front) with 3D texture coordinates and a ``slice`` cell array."""
    points, triangles, slice_index = polygons.fan_triangles()
    polydata = polydata_from_arrays(points, triangles)
    valid = np.arange(MAX_POLYGON_VERTICES)[None, :] < polygons.counts[:, None]
    coordinates = numpy_support.numpy_to_vtk(
        np.ascontiguousarray(polygons.texture_coordinates[valid], dtype=np.float32), deep=True)
    coordinates.SetName("TextureCoordinates")
    polydata.GetPointData().SetTCoords(coordinates)
    index = numpy_support.numpy_to_vtk(slice_index.astype(np.int32), deep=True)
    index.SetName("slice")
    polydata.GetCellData().AddArray(index)
    return polydata
