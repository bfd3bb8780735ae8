"""Cut-away tools evaluated per sample: the compact description every renderer takes, and its numba kernels.

Method (source 002: Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009, sections 2.5
and 3.3.1). A *selection volume* - a small tool with its own resolution and an affine transform ``M`` relative to the
data - masks the data per sample: a sample at ``p_d`` is discarded when the tool is non-zero at ``p_s = M^-1 p_d``
("Wenn s != 0, dann verwerfe das Pixel"), so moving the tool never rewrites the data. Section 3.3.1 replaces the
binary test by the difference of distance fields, ``f_data \\ f_tool = max(f_data, -f_tool)`` (negative inside),
which gives smooth cut surfaces with correct normals.

Here every tool is a signed distance ``f`` in mm (negative inside) of a shape in its own frame: a box, a sphere, a
cylinder (axis along the tool's z), a half-space (the side its z axis points into), or a small grid of values (a
binary mask stored as ``(0.5 - m) h`` with ``h`` its mean voxel size, so the sign is exact and the magnitude within
one voxel; or a distance field in mm) read by trilinear interpolation in its own index space. A ``remove`` tool
removes where ``f < 0``, a ``keep`` tool where ``f > 0``; several tools remove the union of their removals. The
combined *removal field* is ::

    g(p) = min_t r_t(p),   r_t = f_t(M_t^-1 p) (remove) or -f_t(M_t^-1 p) (keep)

and a sample is kept where ``g >= 0`` (``binary`` evaluation, source 002's test), or weighted by
``clamp(1/2 + g / w, 0, 1)`` with ``w`` the transition width (one voxel; ``distance`` evaluation: the CSG difference
of 3.3.1 applied to opacity, a smooth, anti-aliased cut). Within ``band`` mm of the cut (``0 <= g < band``) the
renderers shade with the tool's normal ``grad g / |grad g|`` (central differences of ``g``) instead of the data
gradient, whose stencil reaches into the removed region (source 002 pays six extra selection look-ups per gradient
for this; the analytic tool normal costs six evaluations of ``g`` at cut samples only). ``cut_normals=False`` is
the cheap path the source recommends while the tool moves: the data gradient is used as it is.

Coordinates: :class:`ToolSet` matrices take a point of the *renderer's frame* (the volume frame, mm: voxel
``(i, j, k)`` at ``(i sx, j sy, k sz)``) to the tool's frame (mm; for grid tools straight to the grid's continuous
index ``(i, j, k)``). Kernels take points in that frame, in mm, ``(x, y, z)`` order. Arrays are ``(nz, ny, nx)``.

Leap (the selection's own empty-space skipping): inside the removed region a ray marcher may jump over samples that
are surely removed. :func:`leap_at` gives, per tool that removes the sample, a radius (renderer mm) within which every
point is still fully removed, and takes the largest: for a shape, its signed distance (less half the transition
width for ``distance`` evaluation); for a grid tool, the conservative depth table :func:`grid_leap_depths`, made once
per tool (the grid moves with its matrix, so a depth in the tool's own index frame stays valid when it moves). Each
is divided by the largest singular value of the tool's matrix (renderer mm -> tool units), so it stays
conservative for any affine placement.

Numba: the tool set is passed to kernels as the tuple :meth:`ToolSet.packed` (kinds, modes, matrices, parameters
with the leap scales in their last column, grid offsets, grid shapes, grid values followed by the grid leap depths,
settings); an empty tool set costs one comparison per sample. (The leap data rides in the existing arrays rather
than in more tuple members: every array handed to a kernel call is reference-counted.)

Compile time (the conventions of every kernel module): the small helpers that hot loops call are
``@njit(forceinline=True)``, not numba's ``inline="always"``. numba then compiles a helper once per argument types
and LLVM inlines it into each caller, the same machine code, whereas ``inline="always"`` copies the helper's IR into
every call site before type inference, nested helpers included: :func:`removal_normal` (six :func:`removal` calls)
took 10-14 s to compile that way, the cut shear-warp kernel 170 s; with ``forceinline`` well under a second and
about 15 s. numba hands a caller's ``forceinline`` on to the callees it compiles for it, so a plain helper that a
``forceinline`` one calls says ``forceinline=False``. A helper is compiled again for every new argument type, and a
constant argument has a type of its own (``Literal[int](0)``), as does a ``prange`` index (uint64 in the parallel
loop body, int64 where the kernel is typed): callers pass int64 values (``np.int64(0)``, ``np.int64(k)``) and
``np.bool_`` flags instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .sampling import blend_corners

#: Shape codes.
BOX, SPHERE, CYLINDER, HALFSPACE, GRID = 0, 1, 2, 3, 4
SHAPES = {"box": BOX, "sphere": SPHERE, "cylinder": CYLINDER, "plane": HALFSPACE, "grid": GRID}
#: Mode codes: ``remove`` cuts away what is inside, ``keep`` keeps only the inside (a region of interest).
REMOVE, KEEP = 0, 1
MODES = ("remove", "keep")
#: Evaluation codes.
BINARY, DISTANCE = 0, 1
EVALUATIONS = ("binary", "distance")
#: The removal value far from every tool, or outside a grid tool's grid (mm).
FAR = 1.0e9


@dataclass(frozen=True, eq=False)
class ToolSet:
    """Tools in a renderer's frame, as arrays for numba kernels (see the module notes).

    ``kinds``, ``modes`` ``(n,)`` int64; ``matrices`` ``(n, 4, 4)`` float64 (renderer frame mm -> tool frame mm, or
    grid index for grid tools); ``params`` ``(n, 4)`` float64 (box: half sizes; sphere: radius; cylinder: radius and
    half height; grid: the mm per index unit, for the gradient); ``grid_offsets`` ``(n,)`` and ``grid_shapes``
    ``(n, 3)`` (nx, ny, nz) int64 locate each grid tool's values in the flat float32 ``grid_values``. ``evaluation`` is
    ``"binary"`` or ``"distance"``, ``width`` the distance evaluation's transition (mm), ``band`` the depth (mm) within
    which cut samples take the tool's normal, ``cut_normals`` False on the cheap path while a tool moves.
    ``grid_leaps`` (laid out as ``grid_values``) holds the grid tools' leap depth tables (:func:`grid_leap_depths`)
    made for ``leap_key = (evaluation, width)``; ``leap`` False turns the leap off (every sample is tested).
    ``bounds`` False turns the per-ray bounds off (:func:`~algorithms.common.cutaway_bounds.ray_interval`: every
    sample of a ray is tested).
    ``grid_clears`` (laid out as ``grid_values``) holds the grid tools' clearance tables (:func:`grid_clear_depths`)
    made for removal values of at least ``clear_margin``; they serve while every margin a renderer tests against is
    no larger (:meth:`grid_clears_valid`).
    """

    kinds: np.ndarray
    modes: np.ndarray
    matrices: np.ndarray
    params: np.ndarray
    grid_offsets: np.ndarray
    grid_shapes: np.ndarray
    grid_values: np.ndarray
    evaluation: str = "binary"
    width: float = 1.0
    band: float = 1.5
    cut_normals: bool = True
    grid_leaps: np.ndarray | None = None
    leap_key: tuple = ()
    leap: bool = True
    bounds: bool = True
    grid_clears: np.ndarray | None = None
    clear_margin: float = 0.0

    def __post_init__(self) -> None:
        n = len(self.kinds)
        shapes = {"kinds": (n,), "modes": (n,), "matrices": (n, 4, 4), "params": (n, 4), "grid_offsets": (n,),
                  "grid_shapes": (n, 3)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"tool set: {name} must have shape {shape}, got {np.shape(getattr(self, name))}")
        if self.evaluation not in EVALUATIONS:
            raise ValueError(f"tool evaluation must be one of {', '.join(EVALUATIONS)}, got {self.evaluation!r}")
        if not np.all(np.isfinite(self.matrices)) or not np.all(np.isfinite(self.params)):
            raise ValueError("tool matrices and parameters must be finite")
        if not (self.width > 0 and self.band >= 0):
            raise ValueError(f"tool width must be positive and band non-negative (mm), got {self.width}, {self.band}")
        if self.grid_clears is not None and np.shape(self.grid_clears) != np.shape(self.grid_values):
            raise ValueError(f"tool set: grid_clears must have the shape of grid_values {np.shape(self.grid_values)}, "
                             f"got {np.shape(self.grid_clears)}")
        if self.grid_leaps is not None and np.shape(self.grid_leaps) != np.shape(self.grid_values):
            raise ValueError(f"tool set: grid_leaps must have the shape of grid_values {np.shape(self.grid_values)}, "
                             f"got {np.shape(self.grid_leaps)}")

    def __len__(self) -> int:
        return len(self.kinds)

    @classmethod
    def empty(cls) -> "ToolSet":
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4, 4)), np.zeros((0, 4)),
                   np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros(1, np.float32))

    def with_settings(self, **changes) -> "ToolSet":
        """The same tools with other ``evaluation``, ``width``, ``band`` or ``cut_normals``."""
        values = {name: getattr(self, name) for name in self.__dataclass_fields__}
        values.update(changes)
        return ToolSet(**values)

    def in_frame(self, frame_to_old) -> "ToolSet":
        """The tools for a renderer whose frame maps to this set's frame by the 4x4 ``frame_to_old``."""
        matrix = np.asarray(frame_to_old, dtype=np.float64)
        return self.with_settings(matrices=np.ascontiguousarray(self.matrices @ matrix))

    def key(self) -> tuple:
        """A hashable summary (changes when any tool or setting changes; grid values by identity)."""
        return (self.kinds.tobytes(), self.modes.tobytes(), self.matrices.tobytes(), self.params.tobytes(),
                id(self.grid_values), self.evaluation, self.width, self.band, self.cut_normals, id(self.grid_leaps),
                self.leap_key, self.leap, self.bounds, id(self.grid_clears), self.clear_margin)

    def grid_leaps_valid(self) -> bool:
        """True when the grid tools' leap depths were made for this evaluation: any depths serve ``binary`` (they
        were made for ``g < 0`` or the stricter ``g <= -width/2``); ``distance`` needs depths made for its width."""
        if self.grid_leaps is None:
            return False
        return self.evaluation == "binary" or self.leap_key == (self.evaluation, self.width)

    def largest_margin(self) -> float:
        """The largest test margin a renderer can use with these settings (see
        :func:`~algorithms.common.cutaway_bounds.bounds_margin`)."""
        return max(0.0 if self.evaluation == "binary" else 0.5 * self.width, self.band if self.cut_normals else 0.0)

    def grid_clears_valid(self) -> bool:
        """True when the grid tools' clearance tables were made for a margin at least as large as any in use."""
        return self.grid_clears is not None and self.largest_margin() <= self.clear_margin

    def leap_scales(self) -> np.ndarray:
        """Per tool, renderer mm per tool unit of distance (``1 / sigma_max`` of the matrix's linear part: a step
        of ``d`` tool units is at least ``d / sigma_max`` mm in the renderer's frame); 0 where the tool may not leap
        (leaping off, or a grid tool without valid depths)."""
        n = len(self.kinds)
        if n == 0 or not self.leap:
            return np.zeros(n)
        largest = np.linalg.svd(self.matrices[:, :3, :3], compute_uv=False)[:, 0]
        scales = np.where(largest > 0, 1.0 / np.maximum(largest, 1e-300), 0.0)
        if not self.grid_leaps_valid():
            scales[self.kinds == GRID] = 0.0
        return scales

    def packed(self) -> tuple:
        """The tuple the kernels take: ``(kinds, modes, matrices, params, offsets, shapes, values, settings)`` with
        ``params[:, 3]`` the :meth:`leap_scales`, ``values`` the grid values followed by the grid tools' depth tables
        and their clearance tables (each laid out alike, from ``settings[5]`` and ``settings[7]`` on) and ``settings =
        (evaluation code, width mm, band mm, cut normals 0/1, leap 0/1, where the depth tables start, bounds 0/1, where
        the clearance tables start, clearance tables valid 0/1)`` float64."""
        leaps = self.grid_leaps if self.grid_leaps is not None else np.zeros_like(self.grid_values)
        valid = self.grid_clears_valid()
        clears = self.grid_clears if valid else np.zeros_like(self.grid_values)
        size = float(np.size(self.grid_values))
        settings = np.array([EVALUATIONS.index(self.evaluation), self.width, self.band, float(self.cut_normals),
                             float(self.leap), size, float(self.bounds), 2.0 * size, float(valid)])
        params = np.array(self.params, dtype=np.float64)
        if len(params):
            params[:, 3] = self.leap_scales()
        values = np.concatenate([np.ravel(self.grid_values), np.ravel(leaps), np.ravel(clears)]).astype(
            np.float32, copy=False)
        return (np.ascontiguousarray(self.kinds, dtype=np.int64), np.ascontiguousarray(self.modes, dtype=np.int64),
                np.ascontiguousarray(self.matrices, dtype=np.float64),
                np.ascontiguousarray(params), np.ascontiguousarray(self.grid_offsets, dtype=np.int64),
                np.ascontiguousarray(self.grid_shapes, dtype=np.int64), values, settings)


def packed_tools(tools: "ToolSet | None") -> tuple:
    """:meth:`ToolSet.packed` of ``tools``, or of an empty set for None."""
    return (tools if tools is not None else ToolSet.empty()).packed()


# -- kernels ----------------------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, inline="always")
def _grid_value(values, offset, nx, ny, nz, x, y, z):
    """Trilinear value of a grid tool at continuous index ``(x, y, z)``; :data:`FAR` outside its voxel centres."""
    if not (0.0 <= x <= nx - 1 and 0.0 <= y <= ny - 1 and 0.0 <= z <= nz - 1):
        return FAR
    i0 = min(int(x), max(nx - 2, 0))
    j0 = min(int(y), max(ny - 2, 0))
    k0 = min(int(z), max(nz - 2, 0))
    i1, j1, k1 = min(i0 + 1, nx - 1), min(j0 + 1, ny - 1), min(k0 + 1, nz - 1)
    fx, fy, fz = x - i0, y - j0, z - k0
    a = offset + k0 * nx * ny  # the cell's lower (k0) and upper (k1) planes
    b = offset + k1 * nx * ny
    return blend_corners(
        values[a + j0 * nx + i0], values[a + j0 * nx + i1], values[a + j1 * nx + i0], values[a + j1 * nx + i1],
        values[b + j0 * nx + i0], values[b + j0 * nx + i1], values[b + j1 * nx + i0], values[b + j1 * nx + i1],
        fx, fy, fz)


@njit(cache=True, nogil=True, forceinline=True)
def _shape_distance(kind, p0, p1, p2, x, y, z):
    """Signed distance (mm, negative inside) of one analytic tool shape (not a grid tool; parameters ``p0..p2``)
    at ``(x, y, z)`` in the tool's own frame. Scalars only (module notes, compile time)."""
    if kind == SPHERE:
        return math.sqrt(x * x + y * y + z * z) - p0
    if kind == BOX:
        qx, qy, qz = abs(x) - p0, abs(y) - p1, abs(z) - p2
        outside = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
        return outside + min(max(qx, max(qy, qz)), 0.0)
    if kind == CYLINDER:
        qr = math.sqrt(x * x + y * y) - p0
        qh = abs(z) - p1
        outside = math.sqrt(max(qr, 0.0) ** 2 + max(qh, 0.0) ** 2)
        return outside + min(max(qr, qh), 0.0)
    return -z  # HALFSPACE


@njit(cache=True, nogil=True, inline="always")
def to_tool(matrices, t, x, y, z):
    """The point ``(x, y, z)`` (renderer frame) in tool ``t``'s own frame. Indexed in place: a view of one matrix
    would be reference-counted, which costs more than the arithmetic."""
    return (matrices[t, 0, 0] * x + matrices[t, 0, 1] * y + matrices[t, 0, 2] * z + matrices[t, 0, 3],
            matrices[t, 1, 0] * x + matrices[t, 1, 1] * y + matrices[t, 1, 2] * z + matrices[t, 1, 3],
            matrices[t, 2, 0] * x + matrices[t, 2, 1] * y + matrices[t, 2, 2] * z + matrices[t, 2, 3])


@njit(cache=True, nogil=True, inline="always")
def removal(tools, x, y, z):
    """The removal field ``g`` (mm) at ``(x, y, z)`` (renderer frame, mm): negative where a sample is removed."""
    kinds, modes, matrices, params, offsets, shapes, values = (tools[0], tools[1], tools[2], tools[3], tools[4],
                                                               tools[5], tools[6])
    g = FAR
    for t in range(kinds.shape[0]):
        # Each tool's signed distance f (shapes: analytic; grid tools: trilinear, FAR outside the grid).
        lx, ly, lz = to_tool(matrices, t, x, y, z)
        if kinds[t] == GRID:
            f = _grid_value(values, offsets[t], shapes[t, 0], shapes[t, 1], shapes[t, 2], lx, ly, lz)
        else:
            f = _shape_distance(kinds[t], params[t, 0], params[t, 1], params[t, 2], lx, ly, lz)
        r = f if modes[t] == REMOVE else -f
        if r < g:
            g = r
    return g


@njit(cache=True, nogil=True, inline="always")
def visibility(tools, g):
    """The weight (0 .. 1) of a sample whose removal value is ``g``: binary ``g >= 0``, or the smooth ramp
    ``clamp(1/2 + g / width, 0, 1)`` of the distance evaluation."""
    settings = tools[7]
    if settings[0] == BINARY:
        return 1.0 if g >= 0.0 else 0.0
    w = 0.5 + g / settings[1]
    return min(max(w, 0.0), 1.0)


@njit(cache=True, nogil=True)
def removal_normal(tools, x, y, z, h):
    """``grad g / |grad g|`` at ``(x, y, z)`` by central differences ``h`` mm wide (the cut surface's normal,
    pointing out of the removed region); zeros where the gradient vanishes."""
    # One call of removal in a loop, not six: numba inlines each call as a copy of removal and of the helpers it
    # inlines, and six copies took 10 to 14 s to compile. (x - h is x + (-h) exactly.)
    gx = gy = gz = high = 0.0
    for q in range(6):  # +h, then -h, along x, y and z
        axis = q // 2
        step = h if q % 2 == 0 else -h
        g = removal(tools, x + step if axis == 0 else x, y + step if axis == 1 else y, z + step if axis == 2 else z)
        if q % 2 == 0:
            high = g
        elif axis == 0:
            gx = high - g
        elif axis == 1:
            gy = high - g
        else:
            gz = high - g
    norm = math.sqrt(gx * gx + gy * gy + gz * gz)
    if norm > 0.0:
        return gx / norm, gy / norm, gz / norm
    return 0.0, 0.0, 0.0


@njit(cache=True, nogil=True)
def tool_count(tools):
    return tools[0].shape[0]


@njit(cache=True, nogil=True, inline="always")
def _grid_table_entry(values, start, nx, ny, nz, x, y, z, use_table, reach_outside):
    """A grid tool's per-cell table entry (flat table from ``start``) at continuous index ``(x, y, z)`` inside its
    grid (0 unless ``use_table``); outside it, the distance to the grid's box when ``reach_outside``, else 0."""
    if 0.0 <= x <= nx - 1 and 0.0 <= y <= ny - 1 and 0.0 <= z <= nz - 1:
        if use_table and nx >= 2 and ny >= 2 and nz >= 2:
            i0 = min(int(x), nx - 2)
            j0 = min(int(y), ny - 2)
            k0 = min(int(z), nz - 2)
            return np.float64(values[start + (k0 * ny + j0) * nx + i0])
        return 0.0
    if not reach_outside:
        return 0.0
    qx = max(0.0 - x, 0.0, x - (nx - 1))
    qy = max(0.0 - y, 0.0, y - (ny - 1))
    qz = max(0.0 - z, 0.0, z - (nz - 1))
    return math.sqrt(qx * qx + qy * qy + qz * qz)


@njit(cache=True, nogil=True, inline="always")
def leap_at(tools, x, y, z):
    """How far (renderer mm) from ``(x, y, z)`` every point is still fully removed (0: no leap): the largest, over
    the tools that remove the point, of the tool's conservative depth (shapes: ``-r``, less ``width/2`` for the
    distance evaluation; grid tools: their depth table, or for a ``keep`` grid tool outside its grid the distance to
    the grid's box) times the tool's leap scale. Ray marchers leap that far (module notes)."""
    settings = tools[7]
    if settings[4] <= 0.0:
        return 0.0
    kinds, modes, matrices, params, offsets, shapes, values = (tools[0], tools[1], tools[2], tools[3], tools[4],
                                                               tools[5], tools[6])
    base = int(settings[5])  # the depth tables follow the grid values
    margin = 0.0 if settings[0] == BINARY else 0.5 * settings[1]
    best = 0.0
    for t in range(kinds.shape[0]):
        s = params[t, 3]
        if s <= 0.0:
            continue
        depth = 0.0
        lx, ly, lz = to_tool(matrices, t, x, y, z)
        if kinds[t] == GRID:
            # Outside a keep tool's grid everything is removed: as far as the grid's box.
            depth = _grid_table_entry(values, base + offsets[t], shapes[t, 0], shapes[t, 1], shapes[t, 2], lx, ly, lz,
                                      True, modes[t] == KEEP)
        else:
            f = _shape_distance(kinds[t], params[t, 0], params[t, 1], params[t, 2], lx, ly, lz)
            r = f if modes[t] == REMOVE else -f
            depth = -r - margin
        if depth * s > best:
            best = depth * s
    return best


@njit(cache=True, nogil=True, inline="always")
def clear_at(tools, x, y, z, margin):
    """How far (renderer mm) from ``(x, y, z)`` every tool's removal value stays at least ``margin`` (0: no such
    promise): the smallest, over the tools, of the tool's clearance times its leap scale. A shape's clearance is
    ``r - margin`` (a signed distance changes by at most the distance moved); a grid tool's is its clearance table
    (:func:`grid_clear_depths`, made for a margin at least this large), or outside its grid the distance to the
    grid's box for a ``remove`` tool (nothing there is removed) and 0 for a ``keep`` tool. A renderer that found a
    sample clear (``g >= margin``) need not test the samples closer than this: they are kept unchanged."""
    settings = tools[7]
    if settings[4] <= 0.0:
        return 0.0
    kinds, modes, matrices, params, offsets, shapes, values = (tools[0], tools[1], tools[2], tools[3], tools[4],
                                                               tools[5], tools[6])
    base = int(settings[7])  # the clearance tables follow the depth tables
    tables = settings[8] > 0.0
    best = np.inf
    for t in range(kinds.shape[0]):
        s = params[t, 3]
        if s <= 0.0:
            return 0.0
        clearance = 0.0
        lx, ly, lz = to_tool(matrices, t, x, y, z)
        if kinds[t] == GRID:
            # Outside a remove tool's grid nothing is removed: clear as far as the grid's box.
            clearance = _grid_table_entry(values, base + offsets[t], shapes[t, 0], shapes[t, 1], shapes[t, 2], lx, ly,
                                          lz, tables, modes[t] == REMOVE)
        else:
            f = _shape_distance(kinds[t], params[t, 0], params[t, 1], params[t, 2], lx, ly, lz)
            clearance = (f if modes[t] == REMOVE else -f) - margin
        best = min(best, clearance * s)
        if best <= 0.0:
            return 0.0
    return best if best < np.inf else 0.0


def _cell_depths(corner: np.ndarray, outside_in_set: bool) -> np.ndarray:
    """Per trilinear cell (lower corner ``[k, j, i]``; the last layer of each axis 0), a radius (index units)
    around any point of the cell inside which every point lies in cells whose eight corners are all in ``corner``
    (or outside the grid, when ``outside_in_set``): the larger of the Euclidean distance transform between cell
    centres less ``sqrt(3)`` and the chessboard distance less 1 (both conservative); 0 for other cells."""
    from scipy import ndimage

    out = np.zeros(corner.shape, dtype=np.float32)
    if min(corner.shape) < 2:
        return out
    cells = corner[:-1, :-1, :-1].copy()
    for dk in (0, 1):
        for dj in (0, 1):
            for di in (0, 1):
                cells &= corner[dk:dk + cells.shape[0], dj:dj + cells.shape[1], di:di + cells.shape[2]]
    if not cells.any():
        return out
    if outside_in_set:
        padded, inner = cells, (slice(None),) * 3
    else:
        padded = np.pad(cells, 1, constant_values=False)
        inner = (slice(1, -1),) * 3
    if padded.all():  # every cell in the set and nothing outside limits it
        depth = np.full(cells.shape, float(max(cells.shape)), dtype=np.float64)
    else:
        euclidean = ndimage.distance_transform_edt(padded)[inner] - math.sqrt(3.0)
        chessboard = ndimage.distance_transform_cdt(padded, metric="chessboard")[inner] - 1.0
        depth = np.maximum(np.maximum(euclidean, chessboard), 0.0)
    out[:-1, :-1, :-1] = np.where(cells, depth, 0.0)
    return out


def grid_clear_depths(values, mode: str = "remove", margin: float = 0.0) -> np.ndarray:
    """The clearance table of a grid tool (float32, the shape of ``values``; made once per tool and margin).

    A cell is *clear* when all eight corners have a removal value ``r >= margin`` (``r = values`` for ``remove``,
    ``-values`` for ``keep``): trilinear interpolation then stays at least ``margin`` everywhere in it, so its
    samples are kept as they are. The entry is the radius (index units) within which every point lies in clear
    cells (see :func:`grid_leap_depths` for the construction); outside the grid a ``remove`` tool removes nothing
    (clear), a ``keep`` tool everything (not clear).
    """
    array = np.asarray(values, dtype=np.float32)
    if array.ndim != 3:
        raise ValueError(f"a grid tool's values must be a 3-D array (nz, ny, nx), got shape {array.shape}")
    if mode not in MODES or not math.isfinite(margin):
        raise ValueError(f"grid clearance: mode {mode!r} / margin {margin!r} not valid")
    r = array if mode == "remove" else -array
    return _cell_depths(r >= margin, outside_in_set=mode == "remove")


def grid_leap_depths(values, mode: str = "remove", evaluation: str = "binary", width: float = 1.0) -> np.ndarray:
    """The leap depth table of a grid tool (float32, the shape ``(nz, ny, nx)`` of ``values``; made once per tool).

    Entry ``[k, j, i]`` belongs to the trilinear cell whose lower corner is voxel ``(i, j, k)`` (the last layer of
    each axis is unused, 0). A cell is *fully removed* when all eight corners are (``r = values`` for ``remove``,
    ``-values`` for ``keep``; ``r < 0`` for ``binary``, ``r <= -width/2`` for ``distance``): trilinear
    interpolation then stays removed everywhere in it. The entry is a radius (index units) around any point of the
    cell inside which every point lies in fully removed cells: the larger of the Euclidean distance transform
    between cell centres less ``sqrt(3)`` and the chessboard distance less 1 (both conservative), 0 for cells that
    are not fully removed. Outside the grid nothing is removed by a ``remove`` tool (so the grid is padded with
    cells that are not), everything by a ``keep`` tool.
    """
    array = np.asarray(values, dtype=np.float32)
    if array.ndim != 3:
        raise ValueError(f"a grid tool's values must be a 3-D array (nz, ny, nx), got shape {array.shape}")
    if mode not in MODES or evaluation not in EVALUATIONS:
        raise ValueError(f"grid leap depths: mode {mode!r} / evaluation {evaluation!r} unknown")
    r = array if mode == "remove" else -array
    corner = r < 0 if evaluation == "binary" else r <= -0.5 * float(width)
    return _cell_depths(corner, outside_in_set=mode == "keep")


@njit(cache=True, nogil=True)
def cut_normals_on(tools):
    return tools[7][3] > 0.0


@njit(cache=True, nogil=True)
def cut_band(tools):
    return tools[7][2]


@njit(cache=True, nogil=True, parallel=True)
def removal_on_grid(tools, shape, spacing, out):
    """``g`` at every voxel centre of a ``shape`` ``(nz, ny, nx)`` grid with ``spacing`` ``(sx, sy, sz)`` in the
    tools' frame (voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)``), into the float32 array ``out``."""
    nz, ny, nx = shape[0], shape[1], shape[2]
    for k in prange(nz):
        z = k * spacing[2]
        for j in range(ny):
            y = j * spacing[1]
            for i in range(nx):
                out[k, j, i] = removal(tools, i * spacing[0], y, z)


@njit(cache=True, nogil=True, parallel=True)
def removal_at_points(tools, points, out):
    """``g`` at ``points`` ``(n, 3)`` (renderer frame, mm) into ``out`` ``(n,)``."""
    for p in prange(points.shape[0]):
        out[p] = removal(tools, points[p, 0], points[p, 1], points[p, 2])


@njit(cache=True, nogil=True, parallel=True)
def normals_at_points(tools, points, h, out):
    """:func:`removal_normal` at ``points`` ``(n, 3)`` into ``out`` ``(n, 3)``."""
    for p in prange(points.shape[0]):
        nx, ny, nz = removal_normal(tools, points[p, 0], points[p, 1], points[p, 2], h)
        out[p, 0] = nx
        out[p, 1] = ny
        out[p, 2] = nz


def removal_field(tools: ToolSet, shape, spacing) -> np.ndarray:
    """The removal field ``g`` (float32 mm, ``(nz, ny, nx)``) of ``tools`` at the voxel centres of a grid of
    ``shape`` and ``spacing`` in the tools' frame; ``g < 0`` marks removed voxels."""
    shape = tuple(int(n) for n in shape)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"the grid shape must be three positive sizes (nz, ny, nx), got {shape}")
    out = np.empty(shape, dtype=np.float32)
    if len(tools) == 0:
        out.fill(FAR)
        return out
    removal_on_grid(tools.packed(), np.asarray(shape, dtype=np.int64), np.asarray(spacing, dtype=np.float64), out)
    return out


def removal_values(tools: ToolSet, points) -> np.ndarray:
    """``g`` (mm) at ``points`` ``(n, 3)`` in the tools' frame (mm)."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty(len(points), dtype=np.float64)
    removal_at_points(tools.packed(), points, out)
    return out


def removal_normals(tools: ToolSet, points, h: float = 0.25) -> np.ndarray:
    """Unit normals of the cut (``grad g / |grad g|``) at ``points`` ``(n, 3)``, central differences ``h`` mm."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty((len(points), 3), dtype=np.float64)
    normals_at_points(tools.packed(), points, float(h), out)
    return out
