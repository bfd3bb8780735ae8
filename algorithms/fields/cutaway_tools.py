"""Cut-away tools in patient coordinates: shapes with a transform, their compact form for the renderers, masks of
the removed voxels and the CSG difference of a volume and the tools for surfaces.

Method: source 002 (Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009), section 2.5
(a selection volume with its own resolution and an affine transform ``M`` relative to the data; a data sample at
``p_d`` is discarded where the tool is non-zero at ``M^-1 p_d``) and section 3.3.1 (``f_1 \\ f_2 = max(f_1, -f_2)``
on distance fields: smooth cut surfaces with correct normals). The per-sample evaluation is
:mod:`algorithms.common.cutaway`; this module builds the tools and applies them on grids.

A :class:`Tool` is a shape in its own frame placed by a rigid 4x4 ``matrix`` (tool frame -> LPS mm): a box (full
sizes), a sphere (radius), a cylinder (radius and height, axis along the tool's z), a half-space (the side the
plane's normal points into), or a grid of values (a binary mask, or a signed distance field in mm, negative inside)
with its own :class:`~algorithms.common.grid.Grid` and an affine transform applied to it. Rotations are given in
degrees about x, then y, then z (``R = Rz Ry Rx``). Arrays are ``(nz, ny, nx)``; spacing and origin ``(x, y, z)`` mm.

The surface of "data minus tools" (:func:`cut_volume`) is extracted from a copy of the volume in which, at every
voxel, the value is lowered to at most ``iso + K g`` (``g`` the removal field, mm, negative where removed;
``K`` a contrast per mm small enough that, next to the cut, the tool term is the smaller one wherever the data is
well above ``iso``): the CSG difference
``max(f_data, -f_tool)`` written in the volume's own values, so any isosurface extractor caps the cut. With
``binary`` evaluation removed voxels take the background value instead (the stair-stepped cut of a binary mask).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..common.cutaway import (
    EVALUATIONS,
    FAR,
    KEEP,
    MODES,
    REMOVE,
    SHAPES,
    ToolSet,
    grid_clear_depths,
    grid_leap_depths,
    removal_field,
)
from ..common.grid import Grid
from ..common.progress import ProgressCallback, report

#: Largest grid (voxels) a grid tool may hold: tools are small by design (source 002: "in der Regel kleiner").
MAX_TOOL_VOXELS = 64 * 1024 * 1024


def rotation_matrix(degrees) -> np.ndarray:
    """3x3 rotation by angles (degrees) about x, then y, then z: ``Rz @ Ry @ Rx``."""
    ax, ay, az = (math.radians(float(v)) for v in degrees)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def angles_of(rotation) -> tuple[float, float, float]:
    """The x, y, z angles (degrees) of a rotation matrix ``Rz Ry Rx`` (inverse of :func:`rotation_matrix`)."""
    r = np.asarray(rotation, dtype=np.float64)
    ay = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    if abs(r[2, 0]) < 1 - 1e-9:
        ax = math.atan2(r[2, 1], r[2, 2])
        az = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: put everything in x
        ax = math.atan2(-r[1, 2], r[1, 1])
        az = 0.0
    return (math.degrees(ax), math.degrees(ay), math.degrees(az))


def _frame_for_normal(normal) -> np.ndarray:
    """A rotation whose z axis is ``normal`` (unit)."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    return np.column_stack([u, v, n])


@dataclass(frozen=True, eq=False)
class Tool:
    """One cut-away tool (see the module notes). ``shape`` is ``box``, ``sphere``, ``cylinder``, ``plane`` or
    ``grid``; ``matrix`` the rigid 4x4 tool frame -> LPS mm; ``size`` (mm) the box's full sizes, the sphere's
    radius, the cylinder's radius and height; ``mode`` ``remove`` or ``keep``. Grid tools carry ``values``
    ``(nz, ny, nx)`` float32 (inside negative: a mask already converted, see :func:`grid_tool`) on ``grid`` and their
    ``matrix`` is the affine transform applied to that grid."""

    shape: str
    matrix: np.ndarray = field(default_factory=lambda: np.eye(4))
    size: tuple[float, ...] = ()
    mode: str = "remove"
    values: np.ndarray | None = None
    grid: Grid | None = None
    role: str = ""
    visible: bool = True
    label: str = ""
    #: Where a grid tool's values were read from (a file path; "" when they were made in memory), so that a saved
    #: session can read them again.
    source: str = ""
    #: Grid tools' leap depth tables by (mode, evaluation, width): made once per tool and shared by its moved copies
    #: (the depths live in the grid's own index frame, which moves with the matrix).
    leap_cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"unknown tool shape {self.shape!r}; choose one of {', '.join(SHAPES)}")
        if self.mode not in MODES:
            raise ValueError(f"a tool's mode is remove or keep, got {self.mode!r}")
        matrix = np.asarray(self.matrix, dtype=np.float64)
        if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)) or abs(np.linalg.det(matrix[:3, :3])) < 1e-12:
            raise ValueError("a tool's transform must be a finite, invertible 4x4 matrix")
        object.__setattr__(self, "matrix", matrix)
        needed = {"box": 3, "sphere": 1, "cylinder": 2, "plane": 0, "grid": 0}[self.shape]
        size = tuple(float(v) for v in self.size)
        if len(size) != needed or not all(math.isfinite(v) and v > 0 for v in size):
            what = {"box": "three positive full sizes (mm)", "sphere": "a positive radius (mm)",
                    "cylinder": "a positive radius and height (mm)"}.get(self.shape, "no size")
            raise ValueError(f"a {self.shape} tool needs {what}, got {list(self.size)}")
        object.__setattr__(self, "size", size)
        if self.shape == "grid":
            if self.values is None or self.grid is None or np.shape(self.values) != self.grid.shape:
                raise ValueError("a grid tool needs values of its grid's shape (nz, ny, nx)")

    # -- placement --------------------------------------------------------------------------------------------------
    @property
    def centre(self) -> np.ndarray:
        if self.shape == "grid":
            b = np.asarray(self.grid.world_bounds)
            return (self.matrix @ np.append((b[0::2] + b[1::2]) / 2, 1.0))[:3]
        return self.matrix[:3, 3].copy()

    @property
    def rotation_degrees(self) -> tuple[float, float, float]:
        return angles_of(self.matrix[:3, :3])

    def moved(self, *, centre=None, rotation=None, size=None, mode=None, visible=None) -> "Tool":
        """A copy moved to ``centre`` (LPS mm), turned to ``rotation`` (degrees), resized, or in another mode."""
        matrix = self.matrix.copy()
        if rotation is not None:
            matrix[:3, :3] = rotation_matrix(rotation)
        if centre is not None:
            if self.shape == "grid":
                matrix[:3, 3] += np.asarray(centre, dtype=np.float64) - self.centre
            else:
                matrix[:3, 3] = np.asarray(centre, dtype=np.float64)
        return replace(self, matrix=matrix, size=self.size if size is None else tuple(size),
                       mode=self.mode if mode is None else mode, visible=self.visible if visible is None else visible)

    def leap_depths(self, evaluation: str = "binary", width: float = 1.0) -> np.ndarray:
        """The grid tool's leap depth table (:func:`~algorithms.common.cutaway.grid_leap_depths`) for its mode and
        this evaluation, made on first use and kept (moving the tool does not change it)."""
        key = (self.mode, evaluation, float(width) if evaluation == "distance" else 0.0)
        entry = self.leap_cache.get(key)
        if entry is None or entry[0] is not self.values:
            entry = (self.values, grid_leap_depths(self.values, self.mode, evaluation, width))
            self.leap_cache[key] = entry
        return entry[1]

    def clear_depths(self, margin: float = 0.0) -> np.ndarray:
        """The grid tool's clearance table (:func:`~algorithms.common.cutaway.grid_clear_depths`) for its mode and
        this margin (mm of its field), made on first use and kept like :meth:`leap_depths`."""
        key = (self.mode, "clear", float(margin))
        entry = self.leap_cache.get(key)
        if entry is None or entry[0] is not self.values:
            entry = (self.values, grid_clear_depths(self.values, self.mode, float(margin)))
            self.leap_cache[key] = entry
        return entry[1]

    def with_matrix(self, matrix) -> "Tool":
        return replace(self, matrix=np.asarray(matrix, dtype=np.float64))

    def world_bounds(self) -> tuple[float, ...]:
        """Axis-aligned LPS bounds of the tool's shape (a half-space: infinite)."""
        if self.shape == "plane":
            return (-math.inf, math.inf) * 3
        if self.shape == "grid":
            nx, ny, nz = self.grid.dimensions
            corners = np.array([[i, j, k] for k in (0, nz - 1) for j in (0, ny - 1) for i in (0, nx - 1)], float)
            world = self.grid.index_to_world(corners)
            world = world @ self.matrix[:3, :3].T + self.matrix[:3, 3]
        else:
            half = {"box": np.asarray(self.size) / 2, "sphere": np.full(3, self.size[0]),
                    "cylinder": np.array([self.size[0], self.size[0], self.size[1] / 2])}[self.shape]
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
            world = corners @ self.matrix[:3, :3].T + self.matrix[:3, 3]
        low, high = world.min(axis=0), world.max(axis=0)
        return tuple(float(v) for pair in zip(low, high) for v in pair)

    def describe(self) -> dict:
        """JSON-ready description (LPS mm, degrees)."""
        out = {"shape": self.shape, "mode": self.mode, "centre_mm": [round(float(v), 4) for v in self.centre],
               "rotation_degrees": [round(v, 4) for v in self.rotation_degrees]}
        if self.shape == "box":
            out["size_mm"] = list(self.size)
        elif self.shape == "sphere":
            out["radius_mm"] = self.size[0]
        elif self.shape == "cylinder":
            out["radius_mm"], out["height_mm"] = self.size
        elif self.shape == "plane":
            out["normal"] = [round(float(v), 6) for v in self.matrix[:3, 2]]
        else:
            out.update(role=self.role, grid=self.grid.describe(), matrix=self.matrix.tolist())
        if self.label:
            out["label"] = self.label
        return out


# -- making tools ---------------------------------------------------------------------------------------------------
def _placed(centre, rotation=(0.0, 0.0, 0.0)) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = rotation_matrix(rotation)
    matrix[:3, 3] = np.asarray(centre, dtype=np.float64)
    return matrix


def sphere_tool(centre, radius: float, *, mode: str = "remove") -> Tool:
    return Tool("sphere", _placed(centre), (radius,), mode)


def box_tool(centre, sizes, rotation=(0.0, 0.0, 0.0), *, mode: str = "remove") -> Tool:
    return Tool("box", _placed(centre, rotation), tuple(sizes), mode)


def cylinder_tool(centre, radius: float, height: float, rotation=(0.0, 0.0, 0.0), *, mode: str = "remove") -> Tool:
    return Tool("cylinder", _placed(centre, rotation), (radius, height), mode)


def plane_tool(point, normal, *, mode: str = "remove") -> Tool:
    """The half-space on the side ``normal`` points into, bounded by the plane through ``point``."""
    normal = np.asarray(normal, dtype=np.float64).reshape(-1)
    if normal.shape != (3,) or not np.all(np.isfinite(normal)) or not np.linalg.norm(normal) > 0:
        raise ValueError(f"a plane tool needs a finite, non-zero normal, got {normal.tolist()}")
    matrix = np.eye(4)
    matrix[:3, :3] = _frame_for_normal(normal)
    matrix[:3, 3] = np.asarray(point, dtype=np.float64)
    return Tool("plane", matrix, (), mode)


def grid_tool(values, grid: Grid, *, role: str = "mask", transform=None, mode: str = "remove",
              label: str = "") -> Tool:
    """A tool from a field on its own grid: a binary ``mask`` (non-zero inside) or a signed ``distance`` field (mm,
    negative inside), placed by the affine ``transform`` (4x4, applied to the grid's LPS positions; default
    identity). Refuses grids above :data:`MAX_TOOL_VOXELS` (stating the size)."""
    array = np.asarray(values)
    if not isinstance(grid, Grid) or array.shape != grid.shape:
        raise ValueError(f"a grid tool's values must have its grid's shape {getattr(grid, 'shape', None)}, "
                         f"got {array.shape}")
    if array.size > MAX_TOOL_VOXELS:
        raise ValueError(f"a grid tool of {array.size:,} voxels ({array.size * 4 / 2**30:.2f} GiB as float32) is "
                         f"too large; at most {MAX_TOOL_VOXELS:,} voxels (resample it coarser)")
    if not np.all(np.isfinite(array)):
        raise ValueError("a grid tool's values must be finite")
    if role == "mask":
        step = float(np.mean(grid.spacing))
        field_values = ((0.5 - (array != 0)) * step).astype(np.float32)
    elif role == "distance":
        field_values = array.astype(np.float32)
    else:
        raise ValueError(f"a grid tool's role is mask or distance, got {role!r}")
    matrix = np.eye(4) if transform is None else np.asarray(transform, dtype=np.float64)
    return Tool("grid", matrix, (), mode, values=np.ascontiguousarray(field_values), grid=grid, role=role,
                label=label)


def mesh_tool(points, triangles, *, voxels: int = 64, mode: str = "remove", transform=None,
              progress: ProgressCallback = None) -> Tool:
    """A tool shaped like a closed triangle mesh (LPS mm): voxelised on a grid of ``voxels`` along its longest side
    by :func:`algorithms.fields.voxelise.voxelise` (source 002, 2.2) and used as a binary grid tool."""
    from .voxelise import voxelise  # here: the voxelisation kernels and SciPy load only for mesh-shaped tools

    points = np.asarray(points, dtype=np.float64)
    bounds = [v for axis in range(3) for v in (points[:, axis].min(), points[:, axis].max())]
    grid = Grid.around(bounds, voxels=int(voxels), padding=2)
    mask = voxelise(points, triangles, grid, progress=progress)
    return grid_tool(mask, grid, role="mask", transform=transform, mode=mode, label="mesh")


# -- the compact form -----------------------------------------------------------------------------------------------
def tool_set(tools, frame_to_world=None, *, evaluation: str = "binary", width: float = 1.0, band: float | None = None,
             cut_normals: bool = True) -> ToolSet:
    """The visible ``tools`` as a :class:`~algorithms.common.cutaway.ToolSet` for a renderer whose frame maps to
    LPS mm by ``frame_to_world`` (4x4; default identity). ``width``: the distance evaluation's transition (mm; pass
    the smallest voxel spacing); ``band``: depth of cut shading (mm; default 1.5 ``width``). With a binary-mask grid
    tool the band stays below the mask's level ``h/2`` (its field is ``+-h/2`` away from the cut, see
    :func:`grid_tool`): otherwise every kept sample in the tool's grid box would count as "on the cut" and be shaded
    with a vanishing tool gradient instead of the data's."""
    if evaluation not in EVALUATIONS:
        raise ValueError(f"the cut evaluation is binary or distance, got {evaluation!r}")
    frame = np.eye(4) if frame_to_world is None else np.asarray(frame_to_world, dtype=np.float64)
    tools = [tool for tool in tools if tool.visible]
    n = len(tools)
    kinds = np.zeros(n, np.int64)
    modes = np.zeros(n, np.int64)
    matrices = np.zeros((n, 4, 4))
    params = np.zeros((n, 4))
    offsets = np.zeros(n, np.int64)
    shapes = np.zeros((n, 3), np.int64)
    chunks, leaps, grids, offset = [], [], [], 0
    saturation = math.inf  # the smallest level of a binary-mask grid tool (mm, its field is +-level off the cut)
    for t, tool in enumerate(tools):
        kinds[t] = SHAPES[tool.shape]
        modes[t] = REMOVE if tool.mode == "remove" else KEEP
        if tool.shape == "grid":
            index_of_world = np.linalg.inv(tool.grid.affine)
            matrices[t] = index_of_world @ np.linalg.inv(tool.matrix) @ frame
            offsets[t] = offset
            shapes[t] = tool.grid.dimensions
            chunks.append(tool.values.ravel())
            leaps.append(tool.leap_depths(evaluation, width).ravel())
            grids.append(tool)
            if tool.role == "mask":
                saturation = min(saturation, 0.5 * float(np.mean(tool.grid.spacing)))
            offset += tool.values.size
        else:
            matrices[t] = np.linalg.inv(tool.matrix) @ frame
            if tool.shape == "box":
                params[t, :3] = np.asarray(tool.size) / 2
            elif tool.shape == "sphere":
                params[t, 0] = tool.size[0]
            elif tool.shape == "cylinder":
                params[t, :2] = tool.size[0], tool.size[1] / 2
    values = np.concatenate(chunks).astype(np.float32, copy=False) if chunks else np.zeros(1, np.float32)
    grid_leaps = np.concatenate(leaps).astype(np.float32, copy=False) if leaps else None
    band = min(1.5 * width if band is None else band, 0.99 * saturation)
    # The clearance tables serve every renderer of this set: made for the largest margin any of them tests against.
    margin = max(0.0 if evaluation == "binary" else 0.5 * float(width), float(band))
    grid_clears = (np.concatenate([tool.clear_depths(margin).ravel() for tool in grids]).astype(np.float32, copy=False)
                   if grids else None)
    return ToolSet(kinds, modes, matrices, params, offsets, shapes, values, evaluation, float(width), float(band),
                   bool(cut_normals), grid_leaps, (evaluation, float(width)), grid_clears=grid_clears,
                   clear_margin=margin)


def removed_mask(tools: ToolSet, shape, spacing) -> np.ndarray:
    """Boolean ``(nz, ny, nx)``: the voxels (centres, in the tools' frame) that ``tools`` remove (``g < 0``)."""
    return removal_field(tools, shape, spacing) < 0


def masked_copy(array, tools: ToolSet, spacing, background: float | None = None) -> np.ndarray:
    """A copy of ``array`` with the removed voxels set to ``background`` (default: the array's minimum): the
    "pre-masked" volume of source 002's section 2.5 (what the renderers avoid building per move)."""
    out = np.array(array, copy=True)
    fill = float(np.min(out)) if background is None else float(background)
    out[removed_mask(tools, out.shape, spacing)] = fill
    return out


def cut_volume(array, tools: ToolSet, spacing, iso: float, *, progress: ProgressCallback = None) -> np.ndarray:
    """The volume whose ``iso`` surface is the surface of the data minus the tools, cut capped (module notes).

    Binary evaluation: removed voxels set to the array's minimum (or ``iso - 1`` if that is higher). Distance
    evaluation: ``min(value, iso + K g)`` with ``K = (max - iso) / (8 |spacing|)`` per mm, so the cut face lies
    where ``g = 0`` between voxels (linear interpolation of the tool's distance: smooth, with the tool's normals).
    Returns float32 for distance evaluation, the array's dtype (or float32) for binary.
    """
    values = np.asarray(array)
    g = removal_field(tools, values.shape, spacing)
    report(progress, 0.5)
    low, high = float(values.min()), float(values.max())
    if tools.evaluation == "binary":
        out = np.array(values, copy=True)
        fill = min(low, iso - 1.0)
        if not np.can_cast(np.asarray(fill).dtype, out.dtype, casting="same_kind") or fill < low:
            out = out.astype(np.float32)
        out[g < 0] = fill
    else:
        # Small enough that next to the cut (|g| up to one voxel diagonal) the tool term stays below the data that
        # is above iso, so marching cubes interpolates g itself there (the cut face lies where g = 0); any K > 0
        # puts removed voxels below iso.
        reach = float(np.linalg.norm(spacing))
        contrast = max(high - iso, 1e-6) / (8.0 * reach)
        g = np.minimum(g, np.float32(FAR / 2))  # far from every tool: no change (and no overflow)
        out = np.minimum(values.astype(np.float32), np.float32(iso) + np.float32(contrast) * g)
    report(progress, 1.0)
    return out


def kept_bounds(tools, world_bounds) -> tuple[float, ...]:
    """LPS bounds of what ``keep`` tools leave of ``world_bounds`` (the intersection with each keep tool's bounds);
    ``world_bounds`` itself when no visible tool is in keep mode."""
    low = np.asarray(world_bounds[0::2], dtype=np.float64)
    high = np.asarray(world_bounds[1::2], dtype=np.float64)
    for tool in tools:
        if tool.visible and tool.mode == "keep":
            b = np.asarray(tool.world_bounds())
            low, high = np.maximum(low, b[0::2]), np.minimum(high, b[1::2])
    return tuple(float(v) for pair in zip(low, high) for v in pair)


__all__ = [
    "MAX_TOOL_VOXELS", "Tool", "angles_of", "box_tool", "cut_volume", "cylinder_tool", "grid_tool", "kept_bounds",
    "masked_copy", "mesh_tool", "plane_tool", "removed_mask", "rotation_matrix", "sphere_tool", "tool_set",
]
