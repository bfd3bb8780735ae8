"""The FORBILD head phantom, sampled on a CT grid with partial volumes, on a CT table.

The phantom is Lauritsch and Bruder's analytic head of the FORBILD project (G. Lauritsch, H. Bruder, *Head phantom*,
FORBILD, Institute of Medical Physics, University of Erlangen-Nuremberg, 2001; the 2D slice is documented in Z. Yu,
F. Noo, F. Dennerlein, A. Wunderlich, G. Lauritsch, J. Hornegger, *Simulation tools for two-dimensional experiments
in x-ray computed tomography using the FORBILD head phantom*, Phys. Med. Biol. 57(13), N237, 2012): a skull (two
ellipsoids), the brain, a lower-density region behind the centre, the frontal sinus, the eyes, low-contrast spheres,
a subdural lesion, bony structures of the skull base (ellipsoids, elliptic cylinders and the two cones of the
occiput), the right inner ear (a half ellipsoid of petrous bone holding a hexagonal lattice of 1.5 mm air cells) and
a resolution pattern of small bone rods on the left. Its numbers (centres, semi-axes, axes and densities, in cm and
in densities relative to water) are the published definition; this module is our own code.

Voxelscope adds what a patient's scan has and the definition lacks, each marked :attr:`Shape.addition`: a 4 mm
scalp of soft tissue (40 HU) over the skull, a foam head rest (-900 HU) and a curved carbon-fibre CT table (2 mm
skins of 200 HU around a -900 HU foam core) under the head, optional CT noise.

Geometry and values
-------------------
The definition's frame (x towards the inner ear, y towards the face, z up, in cm) is the patient's RAS frame, so a
point ``(x, y, z)`` of the definition is ``(-10 x, -10 y, 10 z)`` in LPS millimetres; the head's centre is the LPS
origin. A density ``rho`` (relative to water) is ``1000 (rho - 1)`` HU: brain 50, bone 800, air -1000. Objects are
listed from outside in; a later object replaces what the earlier ones put where it lies (the definition's rule: the
density of a point is that of the innermost object containing it).

Sampling
--------
Each voxel's value is the mean of the phantom over the voxel's box. Every shape has a level function ``g`` with
Lipschitz constant 1 (negative inside), so a box whose centre has ``|g| >`` the box's half-diagonal lies wholly inside
or wholly outside the shape. The coverage of a voxel is found by adaptive subdivision (:func:`coverage`): a box
that a surface may cross is split in two along every axis longer than :data:`SUBVOXEL_MM`, and so on, until the boxes
are that small; the last ones count as cut by a plane at their centre's level. Only the boxes along the surfaces are visited, so the cost
follows the surfaces' area, not the grid's size: the 512 x 512 x 176 sample takes seconds, a coarse test grid less.
Coverage fractions are composited in list order, ``v <- v (1 - f) + value f``, which is the box mean wherever a
later object lies inside the earlier ones (all of this phantom but the few voxels where two surfaces cross).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: LPS millimetres per unit of the definition (cm), with the RAS -> LPS flip of x and y.
_CM_TO_LPS = np.diag([-10.0, -10.0, 10.0])

#: The sample's grid: 512 x 512 pixels of 0.546875 mm (a 280 mm field of view) and 176 slices of 1.5 mm.
SAMPLE_SHAPE = (176, 512, 512)
SAMPLE_SPACING = (0.546875, 0.546875, 1.5)
#: The LPS point (mm) the default grid is centred on: the head is centred on the origin, the table lies behind it
#: (posterior, +y), so the field of view is shifted towards the table to hold both.
GRID_CENTRE = (0.0, 14.0, 0.0)

AIR_HU = -1000.0


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _frame(a_x=None, a_y=None, a_z=None) -> np.ndarray:
    """Rows: the shape's local x, y, z axes (unit, right-handed) from any two of them, as the definition gives them."""
    if a_x is not None and a_y is not None:
        x, y = _unit(a_x), _unit(a_y)
        z = np.cross(x, y)
    elif a_x is not None and a_z is not None:
        x, z = _unit(a_x), _unit(a_z)
        y = np.cross(z, x)
    elif a_y is not None and a_z is not None:
        y, z = _unit(a_y), _unit(a_z)
        x = np.cross(y, z)
    else:
        raise ValueError("a rotated shape needs two of its axes")
    return np.array([x, y, z])


@dataclass(frozen=True)
class Shape:
    """One object of the phantom, in LPS millimetres.

    ``kind`` is ``ellipsoid`` (semi-axes ``size``), ``cylinder`` (an elliptic cylinder along the local z axis:
    semi-axes ``size[0]``, ``size[1]`` and half-length ``size[2]``), ``cone`` (along local z from radius ``size[0]``
    at ``z = -size[2]`` to ``size[1]`` at ``+size[2]``) or ``shell`` (the band between the cylinders of radius
    ``size[0]`` and ``size[1]`` about the local z axis on its side ``y >= 0``, ``|x| <= size[2]``, unbounded along
    z). ``frame`` rows are
    the local axes; ``clips`` are half-spaces ``n . p <= d`` (LPS mm) that cut the shape.
    """

    name: str
    kind: str
    centre: tuple[float, float, float]
    size: tuple[float, float, float]
    hu: float
    frame: np.ndarray = field(default_factory=lambda: np.eye(3))
    clips: tuple[tuple[tuple[float, float, float], float], ...] = ()
    addition: bool = False

    def level(self, points: np.ndarray) -> np.ndarray:
        """A level function of ``points`` (``(..., 3)`` LPS mm): negative inside, Lipschitz constant at most 1 (mm).

        It never exceeds the distance to the surface, so ``|level| > r`` proves a ball of radius ``r`` lies on one
        side; for a thin ellipsoid it can be much smaller than that distance.
        """
        return self._signed(points, estimate=False)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """A first-order estimate of the signed distance (mm) to the surface, good near it: the ellipsoidal terms of
        :meth:`level` divided by the length of their gradient instead of scaled by the smallest semi-axis."""
        return self._signed(points, estimate=True)

    def feature_size(self) -> float:
        """The shape's smallest half-size (mm): boxes are subdivided below it before they count by :meth:`distance`."""
        a, b, c = self.size
        if self.kind == "shell":
            return 0.5 * (b - a)
        if self.kind == "cone":
            return min(a, b, c)
        return min(a, b, c)

    def _signed(self, points: np.ndarray, *, estimate: bool) -> np.ndarray:
        local = (points - np.asarray(self.centre)) @ np.asarray(self.frame).T
        u, v, w = local[..., 0], local[..., 1], local[..., 2]
        a, b, c = self.size
        if self.kind == "ellipsoid":
            g = _ellipsoidal(np.stack([u / a, v / b, w / c]), np.array([a, b, c]), estimate)
        elif self.kind == "cylinder":
            g = np.maximum(_ellipsoidal(np.stack([u / a, v / b]), np.array([a, b]), estimate), np.abs(w) - c)
        elif self.kind == "cone":
            slope = (b - a) / (2.0 * c)
            radius = a + slope * (w + c)
            g = np.maximum((np.sqrt(u * u + v * v) - radius) / math.sqrt(1.0 + slope * slope), np.abs(w) - c)
        elif self.kind == "shell":
            rho = np.sqrt(u * u + v * v)
            g = np.maximum(np.maximum(np.abs(rho - 0.5 * (a + b)) - 0.5 * (b - a), np.abs(u) - c), -v)
        else:  # pragma: no cover - the table below only holds the kinds above
            raise ValueError(f"unknown shape kind {self.kind!r}")
        for normal, offset in self.clips:
            g = np.maximum(g, points @ np.asarray(normal) - offset)
        return g

    def bounds(self) -> np.ndarray:
        """``(2, 3)`` LPS box (mm) that holds the shape (unbounded axes are infinite)."""
        frame = np.asarray(self.frame)
        a, b, c = self.size
        if self.kind == "shell":  # the half v >= 0 of the band, |u| <= c: local v in [sqrt(a^2 - c^2), b]
            near = math.sqrt(max(a * a - c * c, 0.0))
            centre = np.asarray(self.centre) + frame[1] * 0.5 * (near + b)
            extent = np.abs(frame.T) @ np.array([c, 0.5 * (b - near), 1e12])
            extent = np.where(extent >= 1e11, np.inf, extent)
            return np.array([centre - extent, centre + extent])
        if self.kind == "cone":
            half = np.array([max(a, b), max(a, b), c])
        else:
            half = np.array([a, b, c])
        with np.errstate(invalid="ignore"):
            extent = np.abs(frame.T) @ np.where(np.isinf(half), 1e12, half)
        extent = np.where(extent >= 1e11, np.inf, extent)
        centre = np.asarray(self.centre)
        return np.array([centre - extent, centre + extent])


def _ellipsoidal(q: np.ndarray, axes: np.ndarray, estimate: bool) -> np.ndarray:
    """``|q| - 1`` for ``q`` = local coordinates over semi-axes (``(d, ...)``), made a length (mm).

    Scaled by the smallest semi-axis it is 1-Lipschitz and never exceeds the distance (``estimate=False``); divided
    by its gradient's length, ``|sum(q_i e_i / a_i)| / |q|``, it is the first-order distance estimate.
    """
    norm = np.sqrt(np.sum(q * q, axis=0))
    if not estimate:
        return (norm - 1.0) * float(axes.min())
    gradient = np.sqrt(np.sum((q / axes.reshape((-1,) + (1,) * (q.ndim - 1))) ** 2, axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, (norm - 1.0) * norm / np.maximum(gradient, 1e-300), -float(axes.min()))


def _forbild(name, kind, centre_cm, size_cm, rho, frame=None, clips_cm=()) -> Shape:
    """A shape of the definition (cm, RAS, density relative to water) in LPS mm and HU."""
    centre = _CM_TO_LPS @ np.asarray(centre_cm, dtype=np.float64)
    flip = _CM_TO_LPS / 10.0  # RAS -> LPS for directions
    local = np.eye(3) if frame is None else np.asarray(frame)
    frame_lps = (flip @ local.T).T  # rows: local axes in LPS
    clips = tuple((tuple(flip @ _unit(n)), 10.0 * d) for n, d in clips_cm)
    return Shape(name, kind, tuple(centre), tuple(10.0 * np.asarray(size_cm, dtype=np.float64)),
                 1000.0 * (rho - 1.0), frame_lps, clips)


def _deg(d: float) -> float:
    return math.radians(d)


def forbild_shapes(*, scalp: bool = True, table: bool = True) -> list[Shape]:
    """The phantom's objects in painting order (outside in): Voxelscope's table and scalp, then the definition."""
    shapes: list[Shape] = []
    if table:
        # A carbon-fibre couch curved about an axis 600 mm in front of its top (its sides rise towards the patient),
        # 440 mm wide; its top is 132 mm behind the head's centre under the occiput. A foam head rest fills the gap.
        radius, top = 600.0, 132.0
        axis = (0.0, top - radius, 0.0)
        # The rest first: the table is painted over the part of its box that the table's curve takes.
        shapes.append(Shape("head rest", "cylinder", (0.0, top + 2.0, 0.0), (85.0, 50.0, 1e6), -900.0,
                            clips=(((0.0, 1.0, 0.0), top),), addition=True))
        shapes.append(Shape("table skin", "shell", axis, (radius, radius + 20.0, 220.0), 200.0, addition=True))
        shapes.append(Shape("table core", "shell", axis, (radius + 2.0, radius + 18.0, 218.0), -900.0,
                            addition=True))
    if scalp:
        shapes.append(Shape("scalp", "ellipsoid", (0.0, 0.0, 0.0), (100.0, 124.0, 129.0), 40.0, addition=True))

    c15, s15 = math.cos(_deg(15)), math.sin(_deg(15))
    c30, s30 = math.cos(_deg(30)), math.sin(_deg(30))
    shapes += [
        _forbild("skull (5)", "ellipsoid", (0, 0, 0), (9.6, 12.0, 12.5), 1.800),
        _forbild("brain (6)", "ellipsoid", (0, 0, 0), (9.0, 11.4, 11.9), 1.050),
        _forbild("ellipsoid 12 (45 HU)", "ellipsoid", (0, -3.6, 0), (1.8, 3.6, 3.6), 1.045),
        _forbild("frontal sinus (7)", "ellipsoid", (0, 8.4, 0), (1.8, 3.0, 3.0), 0.0),
        _forbild("left eye (1)", "ellipsoid", (-4.7, 4.3, 0.872), (2.0, 2.0, 2.0), 1.060),
        _forbild("right eye (2)", "ellipsoid", (4.7, 4.3, 0.872), (2.0, 2.0, 2.0), 1.060),
        _forbild("low-contrast sphere 3 (52.5 HU)", "ellipsoid", (-1.08, -9.0, 0), (0.4, 0.4, 0.4), 1.0525),
        _forbild("low-contrast sphere 4 (47.5 HU)", "ellipsoid", (1.08, -9.0, 0), (0.4, 0.4, 0.4), 1.0475),
        _forbild("bone cylinder 14", "cylinder", (0, 3.6, 0), (1.2, 4.0, 0.25 * c15), 1.800,
                 frame=_frame(a_y=(0, s30, c30), a_z=(0, -c30, s30))),
        _forbild("bone cylinder 15", "cylinder", (0, 9.6, 0), (0.525561, 2.0, 0.2), 1.800,
                 frame=_frame(a_y=(0, -s30, c30), a_z=(1, 0, 0))),
        _forbild("bone ellipsoid 8", "ellipsoid", (-1.9, 5.4, 0), (1.206483 * c15, 0.420276 * c15, 3.0), 1.800,
                 frame=_frame(a_x=(c15 * math.cos(_deg(120)), math.sin(_deg(120)), -s15 * math.cos(_deg(120))),
                              a_z=(s15, 0, c15))),
        _forbild("bone ellipsoid 9", "ellipsoid", (1.9, 5.4, 0), (1.2 * c15, 0.42 * c15, 3.0), 1.800,
                 frame=_frame(a_x=(c15 * math.cos(_deg(60)), math.sin(_deg(60)), s15 * math.cos(_deg(60))),
                              a_z=(-s15, 0, c15))),
        _forbild("bone cylinder 10", "cylinder", (-4.3, 6.8, -1.0), (1.8, 0.24, 2.0), 1.800,
                 frame=_frame(a_x=(math.cos(_deg(150)), math.sin(_deg(150)), 0), a_z=(0, 0, 1))),
        _forbild("bone cylinder 11", "cylinder", (4.3, 6.8, -1.0), (1.8, 0.24, 2.0), 1.800,
                 frame=_frame(a_x=(c30, s30, 0), a_z=(0, 0, 1))),
        _forbild("lesion 13 (55 HU)", "ellipsoid", (6.393945, -6.393945, 0), (1.2, 0.42, 1.2), 1.055,
                 frame=_frame(a_x=(math.cos(_deg(58.1)), math.sin(_deg(58.1)), 0), a_z=(0, 0, 1))),
        # The cones run along y: radius r1 = 0.5 at y - l/2, r2 = 0.2 at y + l/2 (l = 1.5).
        _forbild("occipital cone 16", "cone", (0, -11.15, -0.2), (0.5, 0.2, 0.75), 1.800,
                 frame=_frame(a_x=(0, 0, 1), a_z=(0, 1, 0))),
        _forbild("occipital cone 17", "cone", (0, -11.15, 0.2), (0.5, 0.2, 0.75), 1.800,
                 frame=_frame(a_x=(0, 0, 1), a_z=(0, 1, 0))),
        _forbild("petrous bone (inner ear)", "ellipsoid", (9.1, 0, 0), (4.2, 1.8, 1.8), 1.800,
                 clips_cm=(((1, 0, 0), 9.1),)),
    ]
    shapes += _air_cells()
    shapes += _resolution_pattern()
    return shapes


def _air_cells() -> list[Shape]:
    """The inner ear's 317 air cells: spheres of radius 0.15 cm on a hexagonal close packing of pitch 0.4 cm.

    Layer ``m`` (``z = m h``, ``h = 0.2 sqrt 3`` cm) and row ``n`` (``y = n h``), ``m, n`` in ``-3..3``: the cells
    run along x in steps of 0.4 cm from 8.8 cm (``m + n`` even) or 8.6 cm (odd) down to the row's last x, which the
    definition gives for ``(|m|, |n|)`` in :data:`_AIR_CELL_LAST_X`.
    """
    h = 0.2 * math.sqrt(3.0)
    cells = []
    for m in range(-3, 4):
        for n in range(-3, 4):
            first = 8.8 if (m + n) % 2 == 0 else 8.6
            last = _AIR_CELL_LAST_X[abs(m)][abs(n)]
            for t in range(int(round((first - last) / 0.4)) + 1):
                cells.append(_forbild(f"air cell {m},{n},{t}", "ellipsoid", (first - 0.4 * t, n * h, m * h),
                                      (0.15, 0.15, 0.15), 0.0))
    return cells


#: The last x (cm) of each row of air cells, by layer ``|m|`` and row ``|n|`` (the definition's lattice).
_AIR_CELL_LAST_X = (
    (5.6, 5.8, 6.0, 6.6),
    (5.8, 6.0, 6.2, 6.8),
    (6.0, 6.2, 6.4, 7.0),
    (6.6, 6.8, 7.0, 7.6),
)


def _resolution_pattern() -> list[Shape]:
    """The resolution pattern on the left: 4 x 4 elements, each 5 rods along y and 5 along z (one shared), of bone.

    Element ``(a, b)``: rod diameter ``d_a`` (0.357, 0.312, 0.278, 0.250 mm) across x and y, length ``l_b`` (4, 2, 1,
    0.5 mm) along z; the rods stand at twice their size apart, the elements 0.8 mm apart in x and 4.8 mm in y.
    """
    d0 = 0.04
    diameters = (0.0357, 0.0312, 0.0278, 0.0250)
    lengths = (0.4, 0.2, 0.1, 0.05)
    x0, y0, z0 = -7.0, -1.0, 0.0
    rods = []
    for a, d in enumerate(diameters):
        for b, length in enumerate(lengths):
            x, y = x0 + 2 * a * d0, y0 + 12 * b * d0
            centres = [(x, y + 2 * t * d, z0) for t in range(5)] + [(x, y, z0 + 2 * t * length) for t in range(1, 5)]
            for t, centre in enumerate(centres):
                rods.append(_forbild(f"resolution rod {a + 1}{b + 1}.{t}", "ellipsoid", centre,
                                     (d / 2, d / 2, length / 2), 1.8))
    return rods


def point_values(points, shapes: list[Shape] | None = None) -> np.ndarray:
    """The phantom's value (HU) at ``points`` (``(..., 3)`` LPS mm), without partial volume: the value of the last
    shape holding the point, air where none does."""
    points = np.asarray(points, dtype=np.float64)
    flat = points.reshape(-1, 3)
    values = np.full(len(flat), AIR_HU)
    for item in forbild_shapes() if shapes is None else shapes:
        box = item.bounds()
        near = np.flatnonzero(np.all((flat >= box[0]) & (flat <= box[1]), axis=1))
        values[near[item.level(flat[near]) <= 0.0]] = item.hu
    return values.reshape(points.shape[:-1])


#: Boxes are subdivided until no side is longer than this (mm), or than half a voxel's shortest side on
#: coarse grids, or than the shape's smallest half-size; the last ones count as cut by a plane at their centre's
#: estimated distance.
SUBVOXEL_MM = 0.5


def coverage(shape: Shape, centres: np.ndarray, size) -> np.ndarray:
    """The fraction of each box (``centres`` ``(n, 3)`` LPS mm, sides ``size`` mm) that ``shape`` covers.

    Boxes wholly inside or outside (by the level function's Lipschitz bound) count as 1 or 0; the others are split
    in two along every side longer than :data:`SUBVOXEL_MM` or half the box's shortest side, whichever is
    longer (but never longer than the shape's :meth:`~Shape.feature_size`), recursively; a box that small still crossed by the surface counts as cut by a plane at the estimated
    distance ``d`` (:meth:`Shape.distance`) from its centre: ``clip(1/2 - d / mean side, 0, 1)``, exact for a plane
    parallel to a side.
    """
    count = len(centres)
    fractions = np.zeros(count)
    owner = np.arange(count)
    size = np.asarray(size, dtype=np.float64)
    smallest = min(max(SUBVOXEL_MM, 0.5 * float(size.min())), shape.feature_size())
    weight = 1.0
    while len(centres):
        g = shape.level(centres)
        half_diagonal = 0.5 * float(np.linalg.norm(size))
        fractions += weight * np.bincount(owner[g <= -half_diagonal], minlength=count)
        crossed = np.abs(g) < half_diagonal
        split = size > smallest
        if not split.any():
            # A box this small still crossed counts as cut by a plane at the estimated distance from its centre.
            share = np.clip(0.5 - shape.distance(centres[crossed]) / float(np.mean(size)), 0.0, 1.0)
            fractions += weight * np.bincount(owner[crossed], weights=share, minlength=count)
            break
        steps = [np.array([-0.25, 0.25]) * side if divide else np.zeros(1) for side, divide in zip(size, split)]
        offsets = np.stack(np.meshgrid(*steps, indexing="ij"), axis=-1).reshape(-1, 3)
        centres = (centres[crossed][:, None, :] + offsets[None]).reshape(-1, 3)
        owner = np.repeat(owner[crossed], len(offsets))
        weight /= len(offsets)
        size = np.where(split, 0.5 * size, size)
    return fractions


def grid_origin(shape, spacing, centre=GRID_CENTRE) -> tuple[float, float, float]:
    """The LPS origin (mm) of voxel (0, 0, 0) for a grid of ``shape`` ``(nz, ny, nx)`` centred on ``centre``."""
    nz, ny, nx = shape
    sx, sy, sz = spacing
    return (centre[0] - (nx - 1) / 2 * sx, centre[1] - (ny - 1) / 2 * sy, centre[2] - (nz - 1) / 2 * sz)


def forbild_head_array(
    shape=SAMPLE_SHAPE,
    spacing=SAMPLE_SPACING,
    *,
    origin=None,
    noise_hu: float = 0.0,
    seed: int = 0,
    scalp: bool = True,
    table: bool = True,
    shapes: list[Shape] | None = None,
    progress=None,
) -> np.ndarray:
    """The FORBILD head in HU on an axial grid, an int16 array ``(nz, ny, nx)`` indexed ``[k, j, i]``.

    Parameters
    ----------
    shape : (nz, ny, nx)
        Grid size; the default is the sample's 512 x 512 x 176.
    spacing : (sx, sy, sz)
        Voxel size in mm; the default is 0.546875 x 0.546875 x 1.5 mm.
    origin : (x, y, z), optional
        LPS position (mm) of voxel (0, 0, 0), identity direction; default :func:`grid_origin` (the grid centred
        14 mm behind the head's centre, to hold the table).
    noise_hu : float
        Standard deviation (HU) of CT-like noise: white Gaussian noise blurred in-plane over about a pixel (as a
        reconstruction kernel correlates it), scaled to this deviation; 0 for none.
    seed : int
        Seed of the noise.
    scalp, table : bool
        Include Voxelscope's additions (the scalp; the head rest and the table).
    shapes : list of Shape, optional
        Paint these instead of :func:`forbild_shapes` (for tests of the sampler).
    progress : callable, optional
        Called with the fraction done.

    Returns
    -------
    ndarray of int16, shape (nz, ny, nx)
        Hounsfield units, -1024..3071.
    """
    nz, ny, nx = shape = tuple(int(v) for v in shape)
    if min(shape) < 1:
        raise ValueError(f"the grid needs three positive sizes, got {shape}")
    spacing = tuple(float(v) for v in spacing)
    if min(spacing) <= 0:
        raise ValueError(f"the spacing must be positive (mm), got {spacing}")
    origin = np.asarray(grid_origin(shape, spacing) if origin is None else origin, dtype=np.float64)
    spacing_arr = np.asarray(spacing)
    shapes = forbild_shapes(scalp=scalp, table=table) if shapes is None else shapes

    values = np.full(shape, AIR_HU, dtype=np.float32)
    dims = np.array([nx, ny, nz])

    for index, item in enumerate(shapes):
        box = item.bounds()
        with np.errstate(invalid="ignore"):
            lo = np.floor((box[0] - origin) / spacing_arr - 0.5)
            hi = np.ceil((box[1] - origin) / spacing_arr + 0.5) + 1
        lo = np.clip(np.nan_to_num(lo, neginf=0), 0, dims).astype(int)
        hi = np.clip(np.nan_to_num(hi, posinf=dims.max() + 1), 0, dims).astype(int)
        if np.any(hi <= lo):
            continue
        # Slabs of slices bound the memory of a large shape's centre points.
        slab = max(1, int(4_000_000 // max(1, (hi[0] - lo[0]) * (hi[1] - lo[1]))))
        for k0 in range(lo[2], hi[2], slab):
            k1 = min(hi[2], k0 + slab)
            kk, jj, ii = np.meshgrid(np.arange(k0, k1), np.arange(lo[1], hi[1]), np.arange(lo[0], hi[0]),
                                     indexing="ij")
            centres = origin + np.stack([ii, jj, kk], axis=-1) * spacing_arr
            fraction = coverage(item, centres.reshape(-1, 3), spacing_arr).reshape(centres.shape[:-1])
            touched = fraction > 0
            if touched.any():
                block = values[k0:k1, lo[1]:hi[1], lo[0]:hi[0]]
                f = fraction[touched].astype(np.float32)
                block[touched] = block[touched] * (1.0 - f) + item.hu * f
        if progress is not None:
            progress((index + 1) / len(shapes))

    if noise_hu > 0:
        values += ct_noise(shape, noise_hu, seed=seed)
    return np.clip(np.rint(values), -1024, 3071).astype(np.int16)


def ct_noise(shape, sigma_hu: float, *, seed: int = 0) -> np.ndarray:
    """Zero-mean noise with standard deviation ``sigma_hu``, correlated in-plane over about a pixel, float32.

    White Gaussian noise convolved in each slice with the kernel ``[1, 2, 1] / 4`` along i and j (the smoothing a
    standard reconstruction kernel gives noise), rescaled so that its standard deviation is ``sigma_hu``.
    """
    rng = np.random.default_rng(seed)
    white = rng.standard_normal(size=shape, dtype=np.float32)
    kernel = np.array([0.25, 0.5, 0.25], dtype=np.float32)
    smooth = white
    for axis in (1, 2):
        padded = np.concatenate([np.take(smooth, [0], axis=axis), smooth, np.take(smooth, [-1], axis=axis)],
                                axis=axis)
        n = smooth.shape[axis]
        smooth = (kernel[0] * np.take(padded, range(0, n), axis=axis) + kernel[1] * np.take(padded, range(1, n + 1),
                  axis=axis) + kernel[2] * np.take(padded, range(2, n + 2), axis=axis))
    # Each pass keeps sum(kernel^2) = 3/8 of the variance away from the borders.
    return smooth * np.float32(sigma_hu / (3.0 / 8.0))
