"""Direct volume rendering by texture slicing: view-aligned and axis-aligned stacks of textured polygons.

Method
------
The volume is drawn as a stack of semi-transparent polygons, composited back to front with the over operator
(source 001, technique 3; source 002, 2.4.2-2.4.3)::

    C = C_front * a + C_back * (1 - a)

1. **Slice geometry.** *View-aligned* (source 001; source 002, fig. 2.6): ``count`` planes perpendicular to the
   camera's view direction ``f`` between the nearest and the farthest corner of the box. The depth range
   ``[d_near, d_far]`` is cut into ``count`` slabs of equal thickness ``delta = (d_far - d_near) / count`` and a
   plane is put through the middle of each slab, so no plane merely touches a corner. Each plane is intersected
   with the 12 edges of the box; the cut points form a convex polygon of 3 to 6 vertices. Source 001 orders them
   by solving a travelling-salesman problem (the shortest closed tour, brute force, ``n <= 6``); sorting by angle
   around the centroid gives the same cycle (:func:`shortest_tour_order` is kept for the tests that show it).
   Vertices are ordered counter-clockwise as seen from the camera and triangulated as a fan ``(0, i, i + 1)``;
   each carries its 3D texture coordinate, its position normalised to the box. *Axis-aligned* (source 002,
   fig. 2.5): of the three stacks of slices along x, y and z, the one along the axis with the largest
   ``|f_axis|`` is drawn, one slice through every layer of voxel centres, back to front; the stack switches when
   the largest component changes, and because the two stacks sample the volume at different points the picture
   jumps (source 002's flicker).
2. **Slice textures.** Each slice gets a 2D RGBA texture in its own plane frame: every texel holds the
   trilinearly interpolated scalar at its centre mapped through the transfer function, with the opacity corrected
   for the distance between slices along the view direction (``delta`` for view-aligned slices,
   ``s_axis / |f_axis|`` for axis-aligned ones), as *premultiplied* (associated) colour ``(a r, a g, a b, a)``,
   which interpolates correctly (bilinear filtering of straight colour would mix the colour of transparent texels
   into the border of visible ones). Texel grids: by default a view-aligned slice gets one texel per pixel, its
   centre where the pixel's ray meets the slice, so the texture has the resolution of source 002's 3D texture
   sampled per fragment (its transfer function is looked up per fragment too) and bilinear filtering reads texel
   centres exactly. With ``texel_size`` the grid is anchored at the polygon's corner instead (what a coarser 2D
   texture costs); axis-aligned slices use the voxel grid of their layer (the classic 2D-texture method, bilinear
   within the layer only).
3. **Compositing**, two ways over exactly the same slices and textures:

   - *rasterising* (:class:`SliceStackProp`): one VTK actor per slice, its polygon as fan triangles with 2D
     texture coordinates, an RGBA ``unsigned char`` texture with linear filtering, drawn back to front into the
     render window's 8-bit framebuffer with the blend function ``(ONE, ONE_MINUS_SRC_ALPHA)`` that VTK sets for
     premultiplied textures: ``C = (a c)_front + C_back (1 - a)``, the formula above. Depth writes are off for
     translucent actors in VTK, and the renderer's order-independent translucency must be off (it would replace
     the over operator by a weighted average), as must depth peeling; :meth:`SliceStackProp.attach` sees to it.
   - *float reference* (:class:`SlicingRenderer`): the same formula in float32 per pixel: the pixel's ray meets
     each slice plane at one point (exactly the point whose texture coordinate the rasteriser interpolates
     perspective-correctly), the texture is sampled there bilinearly (clamped to its edge, like GL's
     ``CLAMP_TO_EDGE``), and the sample is composited if the point lies in the polygon, i.e. in the box. With
     ``precision="uint8"`` the accumulation buffer is rounded to 8 bits after every slice, as a framebuffer
     does: source 002 (2.4.3, citing [MB05]) reports errors of up to 40 % after a hundred slices.

Default slice distance (view-aligned): one slice per smallest voxel spacing along the view direction, i.e.
``count = ceil((d_far - d_near) / min(sx, sy, sz))``, so the slices are ``delta <= min(sx, sy, sz)`` apart.

Known approximation: the opacity is corrected for the distance between slices along the central view direction;
for a perspective camera a ray ``theta`` off axis crosses the slabs ``delta / cos(theta)`` apart, so its opacity
is underestimated towards the image corners (by a factor ``cos(theta)``, 0.94 at the corners of a 30 degree view),
as with every planar slice stack on graphics hardware.

Axis order: volume arrays are ``(nz, ny, nx)``, indexed ``[k, j, i]``; spacing and points are ``(x, y, z)`` =
``(i, j, k)``. Everything is in the *volume frame*: voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)`` mm; the box is
the one VTK's volume mappers render, from the first to the last voxel centre.

References
----------
Source 001 (``../shared/seeds/001_5825713f111ed41b.txt``), "Techniek 3: Texture slicing" (plane-box intersection
with the 12 edges, vertex order as a travelling-salesman tour, triangle fans, back-to-front blending
``C = C_voor a + C_achter (1 - a)``). Source 002 (``../shared/seeds/002_e603daa952e6d6b8.txt``), sections 2.4.1-2.4.3
(transfer function lookup, 3D textures, compositing textured polygons: three axis-aligned stacks switched by the
largest component of the view vector, view-aligned polygons of three to six vertices, 8-bit framebuffer error).

K. Engel, M. Hadwiger, J. Kniss, C. Rezk-Salama, D. Weiskopf, "Real-Time Volume Graphics", A K Peters, 2006
(source 002's [EHK+06]), chapter 3: 2D and 3D texture-based slicing, associated colours.
B. Cabral, N. Cam, J. Foran, "Accelerated volume rendering and tomographic reconstruction using texture mapping
hardware", Proc. Symposium on Volume Visualization 1994, 91-98. DOI 10.1145/197938.197972.

Examples
--------
>>> slicer = SlicingRenderer(volume.array, volume.spacing, table)            # view-aligned, float compositing
>>> frame = slicer.render(camera, 512, 512)                                  # camera in the volume frame
>>> stack = SliceStackProp(slicer, user_matrix=volume.local_to_world)        # the same slices as VTK actors
>>> stack.attach(vtk_renderer)
>>> stack.update(camera, 512, 512)                                           # after every camera move
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from numba import njit, prange
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData

from ._progress import ProgressCallback, report
from ._sampling import sample_volume, validated_spacing, validated_volume
from ._vtk import polydata_from_arrays, vtk_matrix
from .camera import Camera
from .render_result import RenderResult
from .transfer import TransferTable

MODES = ("view", "axis")
PRECISIONS = ("float", "uint8")
#: A plane cuts at most six of the twelve box edges.
MAX_POLYGON_VERTICES = 6
#: Corner ``c`` of a box has bit 0, 1, 2 of ``c`` set where it takes the maximum of x, y, z.
_CORNER_BITS = np.array([[(c >> axis) & 1 for axis in range(3)] for c in range(8)], dtype=np.float64)
#: The twelve box edges as pairs of corner indices (the corners differ in exactly one bit).
BOX_EDGES = np.array([(c, c | (1 << axis)) for axis in range(3) for c in range(8) if not c & (1 << axis)],
                     dtype=np.int64)
#: Texels resampled per kernel launch (a chunk of slices; 4 M texels of float32 RGBA are 64 MB).
CHUNK_TEXELS = 1 << 22
#: Relative tolerance (of the box diagonal) below which two cut points are the same vertex.
_MERGE_TOLERANCE = 1e-9


# ------------------------------------------------------------------------------------------------------------
# Slice geometry
# ------------------------------------------------------------------------------------------------------------
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
        ``slice_distance / |normal . f|`` (mm): the step the opacity is corrected for.
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
        within = _ranks_within_groups(fans)  # i - 1 of fan triangle (0, i, i + 1)
        start = first[slice_index]
        triangles = np.stack([start, start + within + 1, start + within + 2], axis=1).astype(np.int64)
        return points, triangles, slice_index


def _ranks_within_groups(sizes: np.ndarray) -> np.ndarray:
    """``0 .. sizes[g] - 1`` for each group ``g`` in turn, e.g. ``[2, 3] -> [0, 1, 0, 1, 2]``."""
    return np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)


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


def _checked_camera(camera) -> Camera:
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be an algorithms.camera.Camera, got {type(camera).__name__}")
    return camera


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
    camera = _checked_camera(camera)
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
    tolerance = _MERGE_TOLERANCE * float(np.linalg.norm(high - low))
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
    camera = _checked_camera(camera)
    low, high = _validated_box(box_min, box_max)
    return _slice_count(camera, low, high, float(validated_spacing(spacing).min()))


def _slice_count(camera: Camera, low: np.ndarray, high: np.ndarray, step: float) -> int:
    """``ceil(depth / step)``: slices at most ``step`` mm apart over the box's depth along the view direction."""
    heights = _box_corners(low, high) @ camera.direction
    return max(1, math.ceil(float(heights.max() - heights.min()) / step - 1e-9))


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
    camera = _checked_camera(camera)
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
    tolerance = _MERGE_TOLERANCE * float(np.linalg.norm(high - low))
    vertices, counts = _order_polygons(corners, np.ones((layers, 4), dtype=bool), u_axis, v_axis, tolerance)
    return SlicePolygons(
        vertices, counts, sign * positions, normal, u_axis, v_axis, float(sizes[axis]),
        float(sizes[axis] / abs(forward[axis])), low, high, axis,
    )


def shortest_tour_order(points) -> np.ndarray:
    """The shortest closed tour through ``points`` by brute force over permutations (source 001's ordering).

    Parameters
    ----------
    points : ndarray, shape (n, 2) or (n, 3)
        ``3 <= n <= 8`` points (a plane-box polygon has at most 6).

    Returns
    -------
    ndarray, shape (n,), int64
        Indices of the points along the shortest closed tour, starting at 0 (its direction is arbitrary).

    Raises
    ------
    ValueError
        If ``points`` is not an ``(n, 2)`` or ``(n, 3)`` array of finite values with ``3 <= n <= 8``.

    Notes
    -----
    ``(n - 1)!`` tours are tried, fixing the first point; source 001 accepted the factorial cost because a
    plane-box polygon never has more than six vertices. For a convex polygon the shortest tour is its boundary
    (a crossing tour can be shortened by the triangle inequality), i.e. the angular order around the centroid.
    """
    array = np.asarray(points, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] not in (2, 3) or not 3 <= len(array) <= 8:
        raise ValueError(f"points must have shape (n, 2) or (n, 3) with 3 <= n <= 8, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError("points must be finite")
    distances = np.linalg.norm(array[:, None] - array[None, :], axis=2)
    tours = np.array([(0, *rest) for rest in itertools.permutations(range(1, len(array)))], dtype=np.int64)
    lengths = distances[tours, np.roll(tours, -1, axis=1)].sum(axis=1)
    return tours[int(np.argmin(lengths))]


# ------------------------------------------------------------------------------------------------------------
# Slice textures
# ------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SliceTexture:
    """The 2D texture of one slice, in the slice's plane frame.

    Texel ``(p, q)`` (column ``p``, row ``q``) is centred at ``origin + (p + 0.5) u_step + (q + 0.5) v_step``, so
    texture coordinates ``(s, t)`` in [0, 1] span ``width`` texels along ``u_step`` and ``height`` along ``v_step``
    (GL's convention: texel centres at ``(p + 0.5) / width``).

    Attributes
    ----------
    origin : ndarray, shape (3,)
        Corner of texel ``(0, 0)`` in the volume frame (mm).
    u_step, v_step : ndarray, shape (3,)
        One texel along the slice's ``u_axis`` and ``v_axis`` (mm).
    rgba : ndarray, shape (height, width, 4), float32
        Premultiplied colour and opacity (opacity corrected for the stack's ``path_step``).
    """

    origin: np.ndarray
    u_step: np.ndarray
    v_step: np.ndarray
    rgba: np.ndarray

    def texture_coordinates(self, points: np.ndarray) -> np.ndarray:
        """``(s, t)`` of points ``(n, 3)`` lying in the slice, ``(n, 2)``."""
        height, width = self.rgba.shape[:2]
        relative = np.asarray(points, dtype=np.float64) - self.origin
        s = relative @ self.u_step / (self.u_step @ self.u_step) / width
        t = relative @ self.v_step / (self.v_step @ self.v_step) / height
        return np.stack([s, t], axis=-1)


@dataclass(frozen=True)
class TextureChunk:
    """The textures of consecutive visible slices in one flat array.

    Attributes
    ----------
    indices : ndarray, shape (m,), int64
        The slices (indices into the layout's polygons), back to front.
    starts : ndarray, shape (m,), int64
        First texel of each texture in ``textures``; texture ``m`` holds ``height * width`` texels, row by row
        (rows along ``v``, ``width`` texels along ``u`` each), ``height, width = layout.shapes[indices[m]]``.
    textures : ndarray, shape (texels, 4), float32
        Premultiplied RGBA.
    """

    indices: np.ndarray
    starts: np.ndarray
    textures: np.ndarray


@dataclass(frozen=True)
class SliceLayout:
    """The slices of one frame, the pixels each can cover and the texel grid of each texture.

    Attributes
    ----------
    polygons : SlicePolygons
        The slices, back to front.
    rows, columns : ndarray, shape (n, 2), int64
        Half-open ranges of image rows (row 0 at the top) and columns whose pixel centres a slice can cover;
        empty ranges for slices outside the image or behind a perspective camera.
    origins, u_steps, v_steps : ndarray, shape (n, 3)
        Texture grid of each slice (see :class:`SliceTexture`).
    shapes : ndarray, shape (n, 2), int64
        ``(height, width)`` of each texture in texels; ``(0, 0)`` for slices that cover no pixel.
    pixel_aligned : bool
        Whether texel centres coincide with the pixel rays (view-aligned slices at the default texel size).
    """

    polygons: SlicePolygons
    rows: np.ndarray
    columns: np.ndarray
    origins: np.ndarray
    u_steps: np.ndarray
    v_steps: np.ndarray
    shapes: np.ndarray
    pixel_aligned: bool

    @property
    def visible(self) -> np.ndarray:
        """``(n,)`` bool: slices that cover at least one pixel centre's range."""
        return self.shapes.min(axis=1) > 0


def _pixel_bounds(polygons: SlicePolygons, camera: Camera, width: int, height: int):
    """Per slice, the half-open pixel row and column ranges ``(n, 2)`` whose centres the polygon can cover.

    Slices wholly behind a perspective camera get empty ranges; slices reaching behind it get the whole image
    (their projection is unbounded).
    """
    n = len(polygons)
    valid = np.arange(MAX_POLYGON_VERTICES)[None, :] < polygons.counts[:, None]
    points = np.nan_to_num(polygons.vertices.reshape(-1, 3))
    depth = ((points - np.asarray(camera.position)) @ camera.direction).reshape(n, -1)
    if camera.parallel_projection:
        in_front = np.ones(n, dtype=bool)
        behind = np.zeros(n, dtype=bool)
    else:
        in_front = np.all(np.where(valid, depth, 1.0) > 0, axis=1)
        behind = np.all(np.where(valid, depth, -1.0) <= 0, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # vertices in the camera's plane project to infinity
        pixels = camera.project(points, width, height).reshape(n, -1, 2)
    low = np.where(valid[..., None], pixels, np.inf).min(axis=1)
    high = np.where(valid[..., None], pixels, -np.inf).max(axis=1)
    # Pixel centres sit at index + 0.5, so the covered indices lie in [low - 0.5, high - 0.5]; one pixel of margin
    # on either side absorbs rounding.
    size = np.array([width, height])
    with np.errstate(invalid="ignore"):
        first = np.clip(np.floor(low - 0.5) - 1, 0, size).astype(np.int64)
        last = np.clip(np.ceil(high - 0.5) + 2, 0, size).astype(np.int64)
    columns = np.where(in_front[:, None], np.stack([first[:, 0], last[:, 0]], axis=1), [0, width])
    rows = np.where(in_front[:, None], np.stack([first[:, 1], last[:, 1]], axis=1), [0, height])
    columns[behind] = 0
    rows[behind] = 0
    return rows.astype(np.int64), columns.astype(np.int64)


def _bounding_textures(polygons: SlicePolygons, u_size: float, v_size: float):
    """Texture grids of ``u_size`` x ``v_size`` mm texels covering each polygon: texel centres from the polygon's
    smallest ``u`` and ``v`` onwards, up to or one texel beyond the largest. Returns origins, u and v steps,
    shapes ``(height, width)``."""
    u = polygons.vertices @ polygons.u_axis
    v = polygons.vertices @ polygons.v_axis
    u_low, u_high = np.nanmin(u, axis=1), np.nanmax(u, axis=1)
    v_low, v_high = np.nanmin(v, axis=1), np.nanmax(v, axis=1)
    widths = np.ceil((u_high - u_low) / u_size - 1e-6).astype(np.int64) + 1
    heights = np.ceil((v_high - v_low) / v_size - 1e-6).astype(np.int64) + 1
    origins = (polygons.offsets[:, None] * polygons.normal + (u_low - 0.5 * u_size)[:, None] * polygons.u_axis
               + (v_low - 0.5 * v_size)[:, None] * polygons.v_axis)
    n = len(polygons)
    u_steps = np.tile(u_size * polygons.u_axis, (n, 1))
    v_steps = np.tile(v_size * polygons.v_axis, (n, 1))
    return origins, u_steps, v_steps, np.stack([heights, widths], axis=1)


def _pixel_textures(polygons: SlicePolygons, camera: Camera, width: int, height: int, rows, columns):
    """Texture grids of view-aligned slices whose texel centres are the points where the pixel rays meet the
    slice: one texel per pixel of the slice's pixel range, texel column ``p`` = image column ``columns[s, 0] + p``,
    texel row ``q`` = image row ``rows[s, 1] - 1 - q`` (texture rows go up, image rows down)."""
    frame = camera.ray_frame(width, height)
    position = np.asarray(camera.position)
    depth = polygons.offsets - polygons.normal @ position  # distance of each plane from the camera along f
    if camera.parallel_projection:
        scale = np.ones(len(polygons))
        corner = frame[0] + (polygons.offsets - frame[0] @ polygons.normal)[:, None] * frame[1]
    else:
        scale = depth  # every pixel ray has f . d = 1, so it meets the plane at t = depth
        corner = position + depth[:, None] * frame[1]
    u_steps = scale[:, None] * frame[2]
    v_steps = -scale[:, None] * frame[3]
    # The centre of pixel (col, row) on the plane is corner + col u_step - row v_step.
    origins = (corner + (columns[:, :1] - 0.5) * u_steps - (rows[:, 1:] - 1 + 0.5) * v_steps)
    shapes = np.stack([rows[:, 1] - rows[:, 0], columns[:, 1] - columns[:, 0]], axis=1)
    return origins, u_steps, v_steps, np.maximum(shapes, 0)


@njit(cache=True, nogil=True, parallel=True)
def _fill_textures(volume, inverse_spacing, box_min, box_max, origins, u_steps, v_steps, widths, starts,
                   row_slices, row_indices, table, table_min, table_scale, out):
    """Premultiplied RGBA of the trilinear scalar at every texel centre of several slice textures.

    Texture ``m`` occupies ``out[starts[m] : starts[m] + height * width]`` (rows of ``widths[m]`` texels); the
    work items are texture rows, ``(row_slices[r], row_indices[r])``, so the threads share rows of all textures.
    Texels farther outside the box than one texel diagonal are never read by bilinear filtering inside the
    polygon; they are set to zero instead of being resampled.
    """
    last = table.shape[0] - 1
    for item in prange(row_slices.shape[0]):
        m = row_slices[item]
        q = row_indices[item]
        width = widths[m]
        base = starts[m] + q * width
        margin = (math.sqrt(u_steps[m, 0] ** 2 + u_steps[m, 1] ** 2 + u_steps[m, 2] ** 2)
                  + math.sqrt(v_steps[m, 0] ** 2 + v_steps[m, 1] ** 2 + v_steps[m, 2] ** 2))
        for p in range(width):
            x = origins[m, 0] + (p + 0.5) * u_steps[m, 0] + (q + 0.5) * v_steps[m, 0]
            y = origins[m, 1] + (p + 0.5) * u_steps[m, 1] + (q + 0.5) * v_steps[m, 1]
            z = origins[m, 2] + (p + 0.5) * u_steps[m, 2] + (q + 0.5) * v_steps[m, 2]
            if (x < box_min[0] - margin or x > box_max[0] + margin or y < box_min[1] - margin
                    or y > box_max[1] + margin or z < box_min[2] - margin or z > box_max[2] + margin):
                for channel in range(4):
                    out[base + p, channel] = 0.0
                continue
            value = sample_volume(volume, x * inverse_spacing[0], y * inverse_spacing[1], z * inverse_spacing[2])
            position = min(max((value - table_min) * table_scale, 0.0), float(last))
            entry = min(int(position), last - 1)
            fraction = position - entry
            alpha = table[entry, 3] + fraction * (table[entry + 1, 3] - table[entry, 3])
            for channel in range(3):
                colour = table[entry, channel] + fraction * (table[entry + 1, channel] - table[entry, channel])
                out[base + p, channel] = alpha * colour
            out[base + p, 3] = alpha


@njit(cache=True, nogil=True)
def _bilinear(textures, channel, base, width, p0, p1, q0, q1, fs, fr):
    """Bilinear interpolation of one channel of the texture at ``base`` between texels ``(q0|q1, p0|p1)``."""
    t00 = textures[base + q0 * width + p0, channel]
    t01 = textures[base + q0 * width + p1, channel]
    t10 = textures[base + q1 * width + p0, channel]
    t11 = textures[base + q1 * width + p1, channel]
    bottom = t00 + fs * (t01 - t00)
    top = t10 + fs * (t11 - t10)
    return bottom + fr * (top - bottom)


@njit(cache=True, nogil=True, parallel=True)
def _composite_slices(accumulator, frame, parallel, normal, plane_offsets, box_min, box_max, tolerance, origins,
                      u_inverse, v_inverse, heights, widths, starts, textures, rows, columns, quantise):
    """Blend slice textures, in the given (back-to-front) order, over ``accumulator (H, W, 4)``:
    ``C = T + (1 - T_alpha) C`` wherever a pixel's ray meets a slice inside the box.

    ``frame`` is :meth:`Camera.ray_frame`. Slice ``m`` lies in the plane ``normal . x = plane_offsets[m]``; its
    texture (layout as in :func:`_fill_textures`) has its texel-(0, 0) corner at ``origins[m]``, and
    ``u_inverse``/``v_inverse`` map an offset from it to texel units (``u_step / |u_step|^2``). ``rows``/
    ``columns`` bound the pixels slice ``m`` can cover. With ``quantise`` every blend is rounded to 8 bits, as a
    framebuffer stores it.
    """
    for row in prange(accumulator.shape[0]):
        for m in range(plane_offsets.shape[0]):
            if row < rows[m, 0] or row >= rows[m, 1]:
                continue
            width = widths[m]
            height = heights[m]
            for col in range(columns[m, 0], columns[m, 1]):
                ox, oy, oz = frame[0, 0], frame[0, 1], frame[0, 2]
                dx, dy, dz = frame[1, 0], frame[1, 1], frame[1, 2]
                shift_x = col * frame[2, 0] + row * frame[3, 0]
                shift_y = col * frame[2, 1] + row * frame[3, 1]
                shift_z = col * frame[2, 2] + row * frame[3, 2]
                if parallel:
                    ox += shift_x
                    oy += shift_y
                    oz += shift_z
                else:
                    dx += shift_x
                    dy += shift_y
                    dz += shift_z
                denominator = normal[0] * dx + normal[1] * dy + normal[2] * dz
                if denominator == 0.0:
                    continue
                t = (plane_offsets[m] - (normal[0] * ox + normal[1] * oy + normal[2] * oz)) / denominator
                if not parallel and t <= 0.0:
                    continue
                x = ox + t * dx
                y = oy + t * dy
                z = oz + t * dz
                if (x < box_min[0] - tolerance or x > box_max[0] + tolerance or y < box_min[1] - tolerance
                        or y > box_max[1] + tolerance or z < box_min[2] - tolerance or z > box_max[2] + tolerance):
                    continue
                rx = x - origins[m, 0]
                ry = y - origins[m, 1]
                rz = z - origins[m, 2]
                s = rx * u_inverse[m, 0] + ry * u_inverse[m, 1] + rz * u_inverse[m, 2] - 0.5
                r = rx * v_inverse[m, 0] + ry * v_inverse[m, 1] + rz * v_inverse[m, 2] - 0.5
                s = min(max(s, 0.0), width - 1.0)  # clamp to the edge texels, like GL_CLAMP_TO_EDGE
                r = min(max(r, 0.0), height - 1.0)
                p0 = min(int(s), max(width - 2, 0))
                q0 = min(int(r), max(height - 2, 0))
                p1 = min(p0 + 1, width - 1)
                q1 = min(q0 + 1, height - 1)
                fs = s - p0
                fr = r - q0
                alpha = _bilinear(textures, 3, starts[m], width, p0, p1, q0, q1, fs, fr)
                if alpha <= 0.0:
                    continue  # VTK's fragment shader discards fully transparent fragments too
                for channel in range(4):
                    if channel == 3:
                        sample = alpha
                    else:
                        sample = _bilinear(textures, channel, starts[m], width, p0, p1, q0, q1, fs, fr)
                    value = sample + (1.0 - alpha) * accumulator[row, col, channel]
                    if quantise:
                        value = math.floor(value * 255.0 + 0.5) / 255.0
                    accumulator[row, col, channel] = value


# ------------------------------------------------------------------------------------------------------------
# The renderer
# ------------------------------------------------------------------------------------------------------------
class SlicingRenderer:
    """Texture-slicing volume renderer with float (or 8-bit emulating) compositing, set up once per volume.

    Parameters
    ----------
    volume_array : ndarray, shape (nz, ny, nx)
        Scalar volume indexed ``[k, j, i]`` (any real dtype; kept as float32), at least 2 voxels per axis.
    spacing : (sx, sy, sz)
        Voxel size in mm; voxel ``(i, j, k)`` sits at ``(i sx, j sy, k sz)`` in the volume frame.
    table : TransferTable
        Colour and opacity per ``table.unit_distance`` mm.
    step : float, optional
        Distance between view-aligned slices in mm: ``count = ceil(depth / step)`` slices. Default (with
        ``slices`` also None): the smallest voxel spacing, one slice per smallest spacing along the view (see
        the module notes; the ray marcher's default step is half that).
    slices : int, optional
        Fixed number of view-aligned slices per frame instead of ``step``.
    mode : {"view", "axis"}
        View-aligned planes (regenerated per camera) or the axis-aligned stack through the voxel centres.
    precision : {"float", "uint8"}
        Accumulate in float32, or round the accumulation buffer to 8 bits after every slice (a framebuffer).
    texel_size : float, optional
        Texel size (mm) of view-aligned slice textures on a grid anchored at each polygon's corner. Default: one
        texel per pixel, its centre where the pixel's ray meets the slice (the texture resolution of a 3D texture
        sampled per fragment). Axis-aligned textures are the voxel grid of their layer.
    progress : callable, optional
        Called with a fraction in [0, 1] during the set-up.

    Raises
    ------
    ValueError
        On a volume that is not 3D, has fewer than 2 voxels along an axis, is not real-valued or holds NaN/inf;
        spacing that is not three positive numbers; an unknown mode or precision; a non-positive ``step``,
        ``slices`` or ``texel_size``; both ``step`` and ``slices``; ``step``, ``slices`` or ``texel_size`` with
        ``mode="axis"`` (its slices and texels are the voxel layers).
    TypeError
        If ``table`` is not a :class:`~algorithms.transfer.TransferTable`.
    """

    def __init__(
        self,
        volume_array,
        spacing,
        table: TransferTable,
        *,
        step: float | None = None,
        slices: int | None = None,
        mode: str = "view",
        precision: str = "float",
        texel_size: float | None = None,
        progress: ProgressCallback = None,
    ) -> None:
        if not isinstance(table, TransferTable):
            raise TypeError(f"table must be an algorithms.transfer.TransferTable, got {type(table).__name__}")
        self.spacing = validated_spacing(spacing)
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
        if step is not None and slices is not None:
            raise ValueError("give either step (mm between slices) or slices (a count), not both")
        if mode == "axis" and (step is not None or slices is not None or texel_size is not None):
            raise ValueError("axis-aligned slices and texels are the voxel layers; step, slices and texel_size "
                             "apply to mode='view' only")
        if step is not None:
            step = float(step)
            if not (math.isfinite(step) and step > 0):
                raise ValueError(f"step must be a positive number of mm, got {step}")
        if slices is not None and (int(slices) != slices or slices < 1):
            raise ValueError(f"slices must be a positive integer, got {slices!r}")
        if texel_size is not None:
            texel_size = float(texel_size)
            if not (math.isfinite(texel_size) and texel_size > 0):
                raise ValueError(f"texel_size must be a positive number of mm, got {texel_size}")
        self.volume = validated_volume(volume_array)
        report(progress, 1.0)
        self.shape = self.volume.shape
        self.table = table
        self.step = step
        self.slices = None if slices is None else int(slices)
        self.mode = mode
        self.precision = precision
        self.texel_size = texel_size
        nz, ny, nx = self.shape
        self.box_min = np.zeros(3)
        self.box_max = (np.array([nx, ny, nz]) - 1) * self.spacing

    # -- geometry ------------------------------------------------------------------------------------------
    def slices_for(self, camera: Camera) -> SlicePolygons:
        """The slice stack this renderer draws for ``camera`` (volume frame), back to front."""
        camera = _checked_camera(camera)
        if self.mode == "axis":
            return axis_aligned_slices(camera, self.box_min, self.box_max, self.spacing)
        if self.slices is not None:
            count = self.slices
        else:
            step = self.step if self.step is not None else float(self.spacing.min())
            count = _slice_count(camera, self.box_min, self.box_max, step)
        return slice_polygons(camera, self.box_min, self.box_max, count)

    def layout(self, camera: Camera, width: int, height: int) -> SliceLayout:
        """The slices for ``camera`` (volume frame), their pixel ranges and texture grids in a ``width`` x
        ``height`` image."""
        camera = _checked_camera(camera)
        if int(width) != width or int(height) != height or width < 1 or height < 1:
            raise ValueError(f"image size must be positive integers, got {width} x {height}")
        width, height = int(width), int(height)
        polygons = self.slices_for(camera)
        rows, columns = _pixel_bounds(polygons, camera, width, height)
        pixel_aligned = polygons.axis is None and self.texel_size is None
        if pixel_aligned:
            grids = _pixel_textures(polygons, camera, width, height, rows, columns)
        elif polygons.axis is None:
            grids = _bounding_textures(polygons, self.texel_size, self.texel_size)
        else:
            grids = _bounding_textures(polygons, float(abs(polygons.u_axis @ self.spacing)),
                                       float(abs(polygons.v_axis @ self.spacing)))
        origins, u_steps, v_steps, shapes = grids
        empty = (rows[:, 1] <= rows[:, 0]) | (columns[:, 1] <= columns[:, 0])
        shapes = np.where(empty[:, None], 0, shapes)
        return SliceLayout(polygons, rows, columns, origins, u_steps, v_steps, shapes, pixel_aligned)

    # -- textures ------------------------------------------------------------------------------------------
    def corrected_table(self, polygons: SlicePolygons) -> np.ndarray:
        """The transfer table ``(n, 4)`` float32 with opacity corrected for ``polygons.path_step``."""
        return np.ascontiguousarray(self.table.corrected(polygons.path_step), dtype=np.float32)

    def texture_chunks(self, layout: SliceLayout) -> Iterator[TextureChunk]:
        """The textures of the visible slices, back to front, a chunk of consecutive slices at a time.

        A texel holds the premultiplied RGBA of the trilinearly interpolated scalar at its centre (clamped to
        the volume: texels beyond the box, read only by bilinear filtering at the polygon's border, hold border
        values), with the opacity corrected for the stack's ``path_step``. Chunks hold about
        ``CHUNK_TEXELS`` texels, so memory stays bounded and each kernel launch has enough work for every thread.
        """
        table = self.corrected_table(layout.polygons)
        inverse_spacing = 1.0 / self.spacing
        visible = np.flatnonzero(layout.visible)
        sizes = layout.shapes[visible, 0] * layout.shapes[visible, 1]
        chunk_of = (np.cumsum(sizes) - sizes) // CHUNK_TEXELS
        for chunk in np.unique(chunk_of):
            indices = visible[chunk_of == chunk]
            heights, widths = layout.shapes[indices, 0], layout.shapes[indices, 1]
            starts = np.concatenate([[0], np.cumsum(heights * widths)[:-1]]).astype(np.int64)
            textures = np.empty((int((heights * widths).sum()), 4), dtype=np.float32)
            row_slices = np.repeat(np.arange(len(indices)), heights)
            row_indices = _ranks_within_groups(heights)
            _fill_textures(self.volume, inverse_spacing, self.box_min, self.box_max, layout.origins[indices],
                           layout.u_steps[indices], layout.v_steps[indices], widths, starts, row_slices,
                           row_indices, table, float(self.table.value_min), float(self.table.scale), textures)
            yield TextureChunk(indices, starts, textures)

    def iter_textures(self, layout: SliceLayout) -> Iterator[tuple[int, SliceTexture]]:
        """``(slice index, texture)`` of every visible slice, back to front (see :meth:`texture_chunks`)."""
        for chunk in self.texture_chunks(layout):
            for m, index in enumerate(chunk.indices):
                height, width = layout.shapes[index]
                rgba = chunk.textures[chunk.starts[m]: chunk.starts[m] + height * width].reshape(height, width, 4)
                yield int(index), SliceTexture(layout.origins[index], layout.u_steps[index], layout.v_steps[index],
                                               rgba)

    # -- frames --------------------------------------------------------------------------------------------
    def render(self, camera: Camera, width: int, height: int, *, progress: ProgressCallback = None) -> RenderResult:
        """One frame seen by ``camera`` (volume frame) at ``width`` x ``height`` pixels.

        Returns
        -------
        RenderResult
            ``rgba`` ``(height, width, 4)`` float32 premultiplied, row 0 at the top; ``stats``: see
            :func:`layout_stats`, plus ``seconds``.
        """
        start = time.perf_counter()
        layout = self.layout(camera, width, height)
        polygons = layout.polygons
        frame = np.ascontiguousarray(camera.ray_frame(int(width), int(height)))
        image = np.zeros((int(height), int(width), 4), dtype=np.float32)
        tolerance = _MERGE_TOLERANCE * float(np.linalg.norm(self.box_max - self.box_min))
        total = max(int(layout.visible.sum()), 1)
        done = 0
        for chunk in self.texture_chunks(layout):
            indices = chunk.indices
            u_steps, v_steps = layout.u_steps[indices], layout.v_steps[indices]
            _composite_slices(
                image, frame, bool(camera.parallel_projection), polygons.normal, polygons.offsets[indices],
                self.box_min, self.box_max, tolerance, layout.origins[indices],
                u_steps / np.sum(u_steps**2, axis=1, keepdims=True),
                v_steps / np.sum(v_steps**2, axis=1, keepdims=True),
                layout.shapes[indices, 0], layout.shapes[indices, 1], chunk.starts, chunk.textures,
                layout.rows[indices], layout.columns[indices], self.precision == "uint8",
            )
            done += len(indices)
            report(progress, done / total)
        return RenderResult(image, {"seconds": time.perf_counter() - start, **layout_stats(layout)})


def layout_stats(layout: SliceLayout) -> dict[str, float]:
    """Numbers describing a frame's slices: ``slices`` (drawn), ``slice_distance_mm``, ``path_step_mm`` (what the
    opacity is corrected for), ``texels`` (resampled in all textures), ``texel_size_mm`` (mean texel edge along
    ``u`` over the drawn slices), ``axis`` (stack axis, -1 for view-aligned slices)."""
    visible = layout.visible
    shapes = layout.shapes[visible]
    texel = np.linalg.norm(layout.u_steps[visible], axis=1)
    return {
        "slices": float(visible.sum()),
        "slice_distance_mm": float(layout.polygons.slice_distance),
        "path_step_mm": float(layout.polygons.path_step),
        "texels": float((shapes[:, 0] * shapes[:, 1]).sum()),
        "texel_size_mm": float(texel.mean()) if len(texel) else 0.0,
        "axis": float(-1 if layout.polygons.axis is None else layout.polygons.axis),
    }


# ------------------------------------------------------------------------------------------------------------
# The rasterising path: VTK actors
# ------------------------------------------------------------------------------------------------------------
class SliceStackProp:
    """The slices of a :class:`SlicingRenderer` as textured VTK polygons, composited by OpenGL.

    One ``vtkActor`` per slice (fan triangles with 2D texture coordinates and an RGBA ``unsigned char`` texture
    with premultiplied colour, linear filtering, clamped to its edge, no lighting), gathered in a ``vtkAssembly``
    in back-to-front order: VTK draws an assembly's parts in order and writes no depth for translucent geometry,
    and the texture's premultiplied flag makes VTK blend with ``(ONE, ONE_MINUS_SRC_ALPHA)``, i.e.
    ``C = C_front a + C_back (1 - a)``.

    Parameters
    ----------
    slicer : SlicingRenderer
        Supplies the slices (mode, count) and their textures; its ``precision`` does not matter here (the
        framebuffer decides).
    user_matrix : ndarray (4, 4), optional
        Placement of the volume frame in the scene (e.g. ``Volume.local_to_world``); identity by default.

    Raises
    ------
    ValueError
        If ``user_matrix`` is not a finite 4x4 matrix.
    TypeError
        If ``slicer`` is not a :class:`SlicingRenderer`.

    Examples
    --------
    >>> stack = SliceStackProp(slicer, user_matrix=volume.local_to_world)
    >>> stack.attach(scene.renderer)            # adds the assembly; order-independent translucency off
    >>> stack.update(volume_frame_camera, 512, 512)
    >>> scene.set_camera(world_camera); scene.render()
    """

    def __init__(self, slicer: SlicingRenderer, *, user_matrix=None) -> None:
        from vtkmodules.vtkRenderingCore import vtkAssembly
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 - the OpenGL mappers and textures must be registered

        if not isinstance(slicer, SlicingRenderer):
            raise TypeError(f"slicer must be a SlicingRenderer, got {type(slicer).__name__}")
        matrix = np.eye(4) if user_matrix is None else np.asarray(user_matrix, dtype=np.float64)
        if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
            raise ValueError(f"user_matrix must be a finite 4x4 matrix, got shape {matrix.shape}")
        self.slicer = slicer
        placement = vtk_matrix(matrix)
        self.prop = vtkAssembly()
        self.prop.SetUserMatrix(placement)
        self._actors: list = []
        self._shown = 0

    def attach(self, renderer) -> None:
        """Add the stack to a ``vtkRenderer`` and switch off what would reorder its blending.

        Order-independent translucency (VTK's default) averages translucent fragments with weights instead of
        applying the over operator in drawing order, and depth peeling is unnecessary for geometry already drawn
        back to front; both are turned off on ``renderer``.
        """
        renderer.SetUseOIT(False)
        renderer.SetUseDepthPeeling(False)
        renderer.AddActor(self.prop)

    def _actor(self, index: int):
        from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkTexture

        while len(self._actors) <= index:
            texture = vtkTexture()
            texture.InterpolateOn()
            texture.RepeatOff()
            texture.EdgeClampOn()
            texture.MipmapOff()
            texture.SetPremultipliedAlpha(True)
            mapper = vtkPolyDataMapper()
            mapper.ScalarVisibilityOff()
            actor = vtkActor()
            actor.SetMapper(mapper)
            actor.SetTexture(texture)
            actor.ForceTranslucentOn()
            properties = actor.GetProperty()
            properties.LightingOff()
            properties.SetColor(1.0, 1.0, 1.0)
            properties.SetOpacity(1.0)
            self._actors.append(actor)
        return self._actors[index]

    def update(self, camera: Camera, width: int, height: int, *, progress: ProgressCallback = None) -> dict:
        """Rebuild the slices and textures for ``camera`` (volume frame) and an image of ``width`` x ``height``.

        Returns the numbers of :func:`layout_stats` plus ``seconds`` spent here (the textures are uploaded to
        OpenGL at the next render).
        """
        start = time.perf_counter()
        layout = self.slicer.layout(camera, width, height)
        _, triangles, triangle_slice = layout.polygons.fan_triangles()
        first_point = np.cumsum(layout.polygons.counts) - layout.polygons.counts
        total = max(int(layout.visible.sum()), 1)
        parts = []
        for done, (index, texture) in enumerate(self.slicer.iter_textures(layout)):
            actor = self._actor(done)
            points = layout.polygons.polygon(index)
            polydata = polydata_from_arrays(points, triangles[triangle_slice == index] - first_point[index])
            coordinates = numpy_support.numpy_to_vtk(
                np.ascontiguousarray(texture.texture_coordinates(points), dtype=np.float32), deep=True)
            coordinates.SetName("TextureCoordinates")
            polydata.GetPointData().SetTCoords(coordinates)
            actor.GetMapper().SetInputData(polydata)
            texel_rows, texel_columns = texture.rgba.shape[:2]
            image = vtkImageData()
            image.SetDimensions(texel_columns, texel_rows, 1)
            scalars = numpy_support.numpy_to_vtk(
                np.clip(np.rint(texture.rgba * 255.0), 0, 255).astype(np.uint8).reshape(-1, 4), deep=True)
            scalars.SetName("rgba")
            image.GetPointData().SetScalars(scalars)
            actor.GetTexture().SetInputData(image)
            parts.append(actor)
            report(progress, (done + 1) / total)
        self._replace_parts(parts)
        return {"seconds": time.perf_counter() - start, **layout_stats(layout)}

    def _replace_parts(self, parts: list) -> None:
        """Show exactly ``parts``, in order (the assembly draws its parts in the order they were added)."""
        for actor in self._actors[: self._shown]:
            self.prop.RemovePart(actor)
        for actor in parts:
            self.prop.AddPart(actor)
        self._shown = len(parts)
        self.prop.Modified()

    @property
    def actors(self) -> list:
        """The actors currently shown, back to front."""
        return self._actors[: self._shown]


# ------------------------------------------------------------------------------------------------------------
# VTK filter: the slice stack as polydata
# ------------------------------------------------------------------------------------------------------------
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


class TextureSlicingFilter(VTKPythonAlgorithmBase):
    """VTK filter around :func:`slice_polygons` / :func:`axis_aligned_slices`: image in, slice stack out.

    Input: a ``vtkImageData`` with the identity direction matrix; its box of voxel centres (origin to
    ``origin + (dims - 1) * spacing``) is sliced for the camera set with :meth:`SetCamera` (in the image's
    coordinates). Output: ``vtkPolyData`` of fan triangles in back-to-front order, point data
    ``TextureCoordinates`` (3D, normalised box coordinates) and cell data ``slice`` (index of the slice, 0
    farthest). Running without a camera, or on an image with another direction matrix, fails with VTK's error
    (:class:`algorithms._vtk.VTKError` from :func:`algorithms._vtk.run_algorithm`).

    Examples
    --------
    >>> from algorithms._vtk import image_from_array, run_algorithm
    >>> f = TextureSlicingFilter()
    >>> f.SetInputDataObject(image_from_array(volume, spacing))
    >>> f.SetCamera(camera)
    >>> f.SetMode("view"); f.SetNumberOfSlices(0)      # 0: one slice per smallest spacing
    >>> polydata = run_algorithm(f)
    """

    def __init__(self) -> None:
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkPolyData")
        self._camera: Camera | None = None
        self._mode = "view"
        self._slices = 0

    def SetCamera(self, camera: Camera) -> None:  # noqa: N802 - VTK naming
        camera = _checked_camera(camera)
        if camera != self._camera:
            self._camera = camera
            self.Modified()

    def GetCamera(self) -> Camera | None:  # noqa: N802
        return self._camera

    def SetMode(self, mode: str) -> None:  # noqa: N802
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        if mode != self._mode:
            self._mode = mode
            self.Modified()

    def GetMode(self) -> str:  # noqa: N802
        return self._mode

    def SetNumberOfSlices(self, count: int) -> None:  # noqa: N802
        """View-aligned slice count; 0 for the default (one slice per smallest voxel spacing)."""
        if int(count) != count or count < 0:
            raise ValueError(f"the number of slices must be a non-negative integer, got {count!r}")
        if int(count) != self._slices:
            self._slices = int(count)
            self.Modified()

    def GetNumberOfSlices(self) -> int:  # noqa: N802
        return self._slices

    def RequestData(self, request, in_info, out_info):  # noqa: N802
        image = vtkImageData.GetData(in_info[0], 0)
        output = vtkPolyData.GetData(out_info, 0)
        if self._camera is None:
            raise ValueError("TextureSlicingFilter needs a camera (SetCamera) before it runs")
        direction = np.array([image.GetDirectionMatrix().GetElement(r, c) for r in range(3) for c in range(3)])
        if not np.allclose(direction, np.eye(3).ravel()):
            raise ValueError("TextureSlicingFilter expects an image with the identity direction matrix")
        spacing = np.asarray(image.GetSpacing(), dtype=np.float64)
        low = np.asarray(image.GetOrigin(), dtype=np.float64)
        high = low + (np.asarray(image.GetDimensions()) - 1) * spacing
        if self._mode == "axis":
            polygons = axis_aligned_slices(self._camera, low, high, spacing)
        else:
            count = self._slices or default_slice_count(self._camera, low, high, spacing)
            polygons = slice_polygons(self._camera, low, high, count)
        output.ShallowCopy(slices_to_polydata(polygons))
        return 1


__all__ = [
    "BOX_EDGES",
    "CHUNK_TEXELS",
    "MAX_POLYGON_VERTICES",
    "MODES",
    "PRECISIONS",
    "SliceLayout",
    "SlicePolygons",
    "SliceStackProp",
    "SliceTexture",
    "SlicingRenderer",
    "TextureChunk",
    "TextureSlicingFilter",
    "axis_aligned_slices",
    "default_slice_count",
    "layout_stats",
    "shortest_tour_order",
    "slice_polygons",
    "slices_to_polydata",
]
