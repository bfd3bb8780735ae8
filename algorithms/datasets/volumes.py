"""Synthetic volumes for tests, benchmarks and the sample data: deterministic by seed, NumPy only.

Every generator returns a NumPy array in Voxelscope's axis order ``(nz, ny, nx)`` (index ``[k, j, i]``); spacing
arguments are ``(sx, sy, sz)`` in mm.

Families
--------
- Source 000 (Dutch BSc thesis on voxel models as triangle strips, see docs/references.md), section 8.2:
  :func:`worst_case`, :func:`spheres`, :func:`pillars`, :func:`scatter`, boolean voxel models of ``n`` voxels per
  side (:data:`FAMILIES`, :func:`family`).
- Source 004 (Tavira Rodríguez de Liébana, *Optimización del renderizado de volumen mediante la técnica
  shear-warping*, 2017), section 6.1: :func:`random_volume`, uint8 volumes where a chosen fraction of voxels is
  transparent (value 0) and the rest random in 1..255.
- Analytic fields with known areas and volumes: :func:`sphere_field`, :func:`ellipsoid_field`,
  :func:`torus_field`.
- :func:`ct_head_array`: a CT head in Hounsfield units (air, skin and soft tissue, a skull of varying thickness
  with thin temporal bone, brain, ventricles, eyes, a cervical vertebra column), with partial-volume edges.
  ``app.datasets.ct_head_phantom`` wraps it in a volume with geometry, units and modality.
"""

from __future__ import annotations

import numpy as np

FAMILIES = ("worst-case", "spheres", "pillars-0", "pillars-20", "pillars-50", "scatter-20", "scatter-50")


def _shape(n) -> tuple[int, int, int]:
    if np.isscalar(n):
        n = (int(n),) * 3
    shape = tuple(int(v) for v in n)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"a volume needs three positive sizes, got {n!r}")
    return shape


# --------------------------------------------------------------------------------------------------------------
# Source 000: voxel-model families
# --------------------------------------------------------------------------------------------------------------
def worst_case(n) -> np.ndarray:
    """3D checkerboard: voxel solid iff ``i + j + k`` is even. Every face of every solid voxel is visible."""
    nz, ny, nx = _shape(n)
    k, j, i = np.ogrid[:nz, :ny, :nx]
    return ((i + j + k) % 2 == 0)


def spheres(n, *, seed: int = 0, count: tuple[int, int] | None = None, radius: tuple[float, float] | None = None):
    """Random solid balls placed uniformly in the cube (source 000, 8.2.2).

    ``count`` bounds the number of balls (default ``(4, 12)``) and ``radius`` their radius in voxels (default
    ``(n/16, n/6)``); both drawn uniformly. Balls may overlap and be cut by the volume's border.
    """
    shape = _shape(n)
    side = min(shape)
    rng = np.random.default_rng(seed)
    count = count or (4, 12)
    radius = radius or (max(1.0, side / 16), max(1.5, side / 6))
    model = np.zeros(shape, dtype=bool)
    for _ in range(int(rng.integers(count[0], count[1] + 1))):
        r = rng.uniform(*radius)
        centre = rng.uniform(0, 1, 3) * np.array(shape)
        lo = np.maximum(np.floor(centre - r).astype(int), 0)
        hi = np.minimum(np.ceil(centre + r).astype(int) + 1, shape)
        if np.any(hi <= lo):
            continue
        kk, jj, ii = np.ogrid[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
        inside = (kk - centre[0]) ** 2 + (jj - centre[1]) ** 2 + (ii - centre[2]) ** 2 <= r * r
        model[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] |= inside
    return model


def pillars(n, *, seed: int = 0, noise: float = 0.0, count: int | None = None, thickness: float | None = None):
    """Random vertical columns (along k, the height axis) with optional noise (source 000, 8.2.3).

    ``count`` columns (default ``n / 4``) of square cross-section with mean side ``thickness`` voxels (default
    ``n / 16``, at least 1) and random height. ``noise`` in ``[0, 1]`` is the fraction of a column's layers whose
    cross-section is randomly grown or shrunk by one voxel on a random side: small variations that break the
    columns into towers of different widths, as in the source's 0 %, 20 % and 50 % noise models.
    """
    if not 0.0 <= noise <= 1.0:
        raise ValueError(f"noise is a fraction in [0, 1], got {noise}")
    nz, ny, nx = shape = _shape(n)
    side = min(ny, nx)
    rng = np.random.default_rng(seed)
    count = count if count is not None else max(1, side // 4)
    thickness = thickness if thickness is not None else max(1.0, side / 16)
    model = np.zeros(shape, dtype=bool)
    for _ in range(count):
        width = max(1, int(round(rng.normal(thickness, thickness / 3))))
        y0, x0 = int(rng.integers(0, max(1, ny - width + 1))), int(rng.integers(0, max(1, nx - width + 1)))
        z0 = int(rng.integers(0, max(1, nz // 4)))
        z1 = int(rng.integers(min(nz, z0 + max(1, nz // 2)), nz + 1))
        for z in range(z0, z1):
            ya, yb, xa, xb = y0, y0 + width, x0, x0 + width
            if noise and rng.random() < noise:
                delta = int(rng.choice((-1, 1)))
                which = int(rng.integers(4))
                if which == 0:
                    ya -= delta
                elif which == 1:
                    yb += delta
                elif which == 2:
                    xa -= delta
                else:
                    xb += delta
            ya, yb = max(0, ya), min(ny, yb)
            xa, xb = max(0, xa), min(nx, xb)
            if yb > ya and xb > xa:
                model[z, ya:yb, xa:xb] = True
    return model


def scatter(n, *, density: float = 0.2, seed: int = 0) -> np.ndarray:
    """Each voxel solid with probability ``density``, independently (source 000, 8.2.4)."""
    if not 0.0 <= density <= 1.0:
        raise ValueError(f"density is a fraction in [0, 1], got {density}")
    return np.random.default_rng(seed).random(_shape(n)) < density


def family(name: str, n, *, seed: int = 0) -> np.ndarray:
    """A model of one of :data:`FAMILIES` by name (``pillars-20`` = 20 % noise, ``scatter-50`` = 50 % density)."""
    if name == "worst-case":
        return worst_case(n)
    if name == "spheres":
        return spheres(n, seed=seed)
    if name.startswith("pillars-"):
        return pillars(n, seed=seed, noise=int(name.split("-")[1]) / 100)
    if name.startswith("scatter-"):
        return scatter(n, density=int(name.split("-")[1]) / 100, seed=seed)
    raise ValueError(f"unknown dataset family {name!r}; choose one of {', '.join(FAMILIES)}")


# --------------------------------------------------------------------------------------------------------------
# Source 004: random classified volumes
# --------------------------------------------------------------------------------------------------------------
def random_volume(shape, *, transparent_fraction: float = 0.0, seed: int = 0) -> np.ndarray:
    """uint8 volume ``shape = (nz, ny, nx)``: a ``transparent_fraction`` of voxels is 0, the rest uniform 1..255.

    With a transfer function whose opacity is zero exactly at 0 and positive above, this is source 004's test
    volume with 100 % (``transparent_fraction=0``) or fewer non-transparent voxels.
    """
    if not 0.0 <= transparent_fraction <= 1.0:
        raise ValueError(f"transparent_fraction is a fraction in [0, 1], got {transparent_fraction}")
    shape = _shape(shape)
    rng = np.random.default_rng(seed)
    volume = rng.integers(1, 256, size=shape, dtype=np.uint8)
    if transparent_fraction > 0:
        volume[rng.random(shape) < transparent_fraction] = 0
    return volume


# --------------------------------------------------------------------------------------------------------------
# Analytic fields (value >= 0 inside, in voxel units; iso 0)
# --------------------------------------------------------------------------------------------------------------
def _centred_grid(shape, spacing):
    nz, ny, nx = shape
    sx, sy, sz = spacing
    z = (np.arange(nz) - (nz - 1) / 2) * sz
    y = (np.arange(ny) - (ny - 1) / 2) * sy
    x = (np.arange(nx) - (nx - 1) / 2) * sx
    return z[:, None, None], y[None, :, None], x[None, None, :]


def sphere_field(shape, radius: float, spacing=(1.0, 1.0, 1.0)) -> np.ndarray:
    """``radius - |p|`` (mm) on a grid centred at the volume centre; the sphere is the level set 0."""
    z, y, x = _centred_grid(_shape(shape), spacing)
    return (radius - np.sqrt(x * x + y * y + z * z)).astype(np.float32)


def ellipsoid_field(shape, semi_axes, spacing=(1.0, 1.0, 1.0)) -> np.ndarray:
    """``1 - sqrt((x/a)^2 + (y/b)^2 + (z/c)^2)`` for semi-axes ``(a, b, c)`` in mm; level set 0."""
    a, b, c = semi_axes
    z, y, x = _centred_grid(_shape(shape), spacing)
    return (1.0 - np.sqrt((x / a) ** 2 + (y / b) ** 2 + (z / c) ** 2)).astype(np.float32)


def torus_field(shape, major: float, minor: float, spacing=(1.0, 1.0, 1.0)) -> np.ndarray:
    """``minor - distance to the circle of radius major`` in the z = 0 plane (mm); level set 0."""
    z, y, x = _centred_grid(_shape(shape), spacing)
    ring = np.sqrt(x * x + y * y) - major
    return (minor - np.sqrt(ring * ring + z * z)).astype(np.float32)


# --------------------------------------------------------------------------------------------------------------
# CT head phantom
# --------------------------------------------------------------------------------------------------------------
def _ellipsoid_distance(x, y, z, centre, semi_axes):
    """Approximate signed distance (mm, negative inside) to an axis-aligned ellipsoid (first-order)."""
    a, b, c = semi_axes
    u, v, w = (x - centre[0]) / a, (y - centre[1]) / b, (z - centre[2]) / c
    f = np.sqrt(u * u + v * v + w * w)
    grad = np.sqrt((u / a) ** 2 + (v / b) ** 2 + (w / c) ** 2)
    return np.where(f > 0, (f - 1.0) * f / np.maximum(grad, 1e-12), -min(a, b, c))


def _smooth_inside(distance, width):
    """Partial-volume fraction of an edge blurred over ``width`` mm: 1 inside, 0 outside (logistic)."""
    return 1.0 / (1.0 + np.exp(np.clip(distance / (0.35 * width), -40, 40)))


def ct_head_array(
    shape=(108, 256, 256),
    spacing=(0.9375, 0.9375, 2.0),
    *,
    noise_hu: float = 0.0,
    seed: int = 0,
) -> np.ndarray:
    """A synthetic CT of a head in Hounsfield units, an int16 array ``(nz, ny, nx)`` (-1024 to 3071 HU).

    Parameters
    ----------
    shape : (nz, ny, nx)
        Grid size; the default matches a typical head CT (256 x 256 in-plane, 108 axial slices).
    spacing : (sx, sy, sz)
        Voxel size in mm.
    noise_hu : float
        Standard deviation of added Gaussian noise in HU (0 for a clean phantom).
    seed : int
        Seed of the noise.

    Notes
    -----
    Geometry is that of an axial series: ``i`` runs right to left (+x in LPS), ``j`` anterior to posterior (+y), ``k``
    inferior to superior (+z), identity direction, centred on the origin (:func:`centred_origin`). Tissue values: air
    -1000, skin/soft tissue 40, brain 30, ventricles 5 (CSF), eyes 10, skull 700-1900 (dense tables, softer diploe) with
    a thickness between about 2 mm (temporal squama) and 9 mm (occiput), a cervical column 400-1200. Edges are blurred
    over about one voxel, as a scanner's point-spread function does.
    """
    nz, ny, nx = shape = _shape(shape)
    sx, sy, sz = (float(v) for v in spacing)
    z = ((np.arange(nz) - (nz - 1) / 2) * sz).astype(np.float32)[:, None, None]
    y = ((np.arange(ny) - (ny - 1) / 2) * sy).astype(np.float32)[None, :, None]
    x = ((np.arange(nx) - (nx - 1) / 2) * sx).astype(np.float32)[None, None, :]
    blur = max(sx, sy, sz)

    # Head: an ellipsoid (LR 76, AP 96, SI 92 mm) centred 8 mm above the volume centre, on a neck.
    head_c = (0.0, 0.0, 8.0)
    head_d = _ellipsoid_distance(x, y, z, head_c, (76.0, 96.0, 92.0))
    neck_d = np.sqrt((x / 55.0) ** 2 + ((y - 10.0) / 60.0) ** 2) * 55.0 - 55.0
    neck_d = np.where(z < head_c[2], neck_d, np.inf)
    body_d = np.minimum(head_d, np.maximum(neck_d, -(z - (-(nz - 1) / 2 * sz) + 1.0)))
    hu = -1000.0 + 1040.0 * _smooth_inside(body_d, blur)

    # Skull: the shell between an outer surface 5 mm under the skin and an inner surface inset by a thickness
    # that varies with direction: thick occiput, thin temporal squama, moderate frontal/parietal bone.
    rel_x, rel_y, rel_z = x - head_c[0], y - head_c[1], z - head_c[2]
    radial = np.sqrt(rel_x**2 + rel_y**2 + rel_z**2) + 1e-6
    dir_x, dir_y, dir_z = rel_x / radial, rel_y / radial, rel_z / radial
    thickness = 5.5 + 3.0 * np.clip(dir_y, 0, None) ** 2 - 3.5 * (dir_x**2) * np.exp(-((dir_z + 0.1) / 0.35) ** 2)
    thickness = np.clip(thickness + 1.0 * dir_z, 1.8, 9.5)
    outer_d = head_d + 5.0
    inner_d = head_d + 5.0 + thickness
    # The cranium is cut by a plane that rises towards the face, so the eyes sit below the frontal bone; a
    # floor (skull base) 3.5 mm thick closes it along that plane.
    base_z = head_c[2] - 55.0 + 40.0 * np.clip((-rel_y / 96.0 - 0.2) / 0.8, 0.0, 1.0)
    cranium = _smooth_inside(base_z - z, blur)
    shell = _smooth_inside(outer_d, blur) * (1.0 - _smooth_inside(inner_d, blur)) * cranium
    depth = np.clip((-outer_d) / thickness, 0.0, 1.0)  # 0 at the outer table, 1 at the inner table
    bone_hu = 1900.0 - 1100.0 * np.sin(np.pi * depth) * np.clip((thickness - 3.0) / 4.0, 0.0, 1.0)
    floor = _smooth_inside(np.abs(z - (base_z + 3.5)) - 3.5, blur) * _smooth_inside(inner_d, blur)
    bone = np.maximum(shell, floor)
    hu = hu * (1.0 - bone) + np.where(shell >= floor, bone_hu, 1300.0) * bone

    # Brain inside the inner table, above the floor.
    brain_fraction = _smooth_inside(inner_d + 1.5, blur) * _smooth_inside(base_z + 8.5 - z, blur)
    brain_fraction = brain_fraction * (1.0 - bone)
    hu = hu * (1.0 - brain_fraction) + 30.0 * brain_fraction
    # Lateral ventricles: two ellipsoids of CSF.
    for side in (-1.0, 1.0):
        ventricle_d = _ellipsoid_distance(x, y, z, (side * 11.0, 5.0, head_c[2] + 8.0), (7.0, 26.0, 12.0))
        ventricle = _smooth_inside(ventricle_d, blur)
        hu = hu * (1.0 - ventricle) + 5.0 * ventricle
    # Eyes: anterior (negative y in LPS), below the frontal bone, in soft tissue.
    for side in (-1.0, 1.0):
        eye_d = _ellipsoid_distance(x, y, z, (side * 30.0, -72.0, head_c[2] - 42.0), (11.0, 11.0, 11.0))
        eye = _smooth_inside(eye_d, blur)
        hu = hu * (1.0 - eye) + 10.0 * eye
    # Cervical column: a bony cylinder behind the airway in the neck.
    column_d = np.sqrt(x**2 + (y - 25.0) ** 2) - 11.0
    column = _smooth_inside(column_d, blur) * _smooth_inside(z - (head_c[2] - 62.0), blur)
    cancellous = _smooth_inside(column_d + 2.5, blur)  # the core of the vertebra is softer than its cortex
    hu = hu * (1.0 - column) + (1200.0 - 400.0 * cancellous) * column
    # Airway: an air tube in front of the column.
    airway = _smooth_inside(np.sqrt(x**2 + (y + 8.0) ** 2) - 7.0, blur) * _smooth_inside(z - (head_c[2] - 60.0), blur)
    hu = hu * (1.0 - airway) - 1000.0 * airway

    if noise_hu > 0:
        hu = hu + np.random.default_rng(seed).normal(0.0, noise_hu, size=shape)
    return np.clip(np.rint(hu), -1024, 3071).astype(np.int16)


def centred_origin(shape, spacing) -> tuple[float, float, float]:
    """The origin ``(x, y, z)`` (mm) that centres a grid of ``shape`` ``(nz, ny, nx)`` and ``spacing`` on 0."""
    nz, ny, nx = _shape(shape)
    sx, sy, sz = (float(v) for v in spacing)
    return (-(nx - 1) / 2 * sx, -(ny - 1) / 2 * sy, -(nz - 1) / 2 * sz)
