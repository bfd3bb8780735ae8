"""Showing an OME-Zarr pyramid larger than memory: open at a coarse level, refine the region in view when zoomed.

Method
------
1. **Open coarse.** :func:`load_pyramid_for_view` reads the finest pyramid level whose samples fit
   :data:`COARSE_BUDGET` (128 MiB: 256^3 of a 1024^3 uint16 volume, 32 MiB), and computes the value range,
   robust range and histogram from that level only (never a pass over level 0). The volume remembers where it came
   from (``metadata["pyramid"]``: store, level, number of levels), so the views know they may refine it.
2. **What is in view.** :func:`visible_box` intersects the camera's view frustum (four side planes through the eye,
   or a prism for a parallel camera) with the volume's box of level-0 sample centres, in the volume frame: the
   vertices of the intersection polytope are the box corners inside the frustum, the crossings of the box edges
   with the frustum planes that lie inside the frustum, and the crossings of the frustum's four corner rays with
   the box. Their axis-aligned bounding box is exactly the part of the volume that can appear on screen.
3. **Which level and region.** :func:`plan_region` maps that box to the sample indices of every level (each
   level's own spacing and origin, one sample of margin) and picks the finest level whose region fits
   :data:`REGION_BUDGET` (128 MiB). If that level is not finer than the coarse level on show, or the whole
   volume is in view, the plan is the coarse volume (``None``): zooming out goes back to it.
4. **Reading.** :func:`read_region` reads the region slab by slab (one chunk row of z at a time, with progress and
   cancel between slabs) into a :class:`~app.volume.Volume` placed at the region's true origin with the level's
   spacing and the volume's direction, so it lines up with the coarse volume and with every other item; its value
   range is the coarse volume's (transfer functions keep their colours).

Array orders: samples ``(nz, ny, nx)``; regions as ``(start, stop)`` index triples in ``(z, y, x)`` = ``(k, j, i)``
order; spacing and origin ``(x, y, z)`` mm (:mod:`app.volume`). The pyramid format is OME-NGFF (J. Moore et al.,
"OME-NGFF: a next-generation file format for expanding bioimaging data-access strategies", 2021); see
:mod:`app.io.zarr` for how its levels are placed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from algorithms.common.camera import Camera
from algorithms.common.progress import ProgressCallback, report

from .io.zarr import open_zarr
from .volume import Volume

__all__ = ["COARSE_BUDGET", "REGION_BUDGET", "RegionPlan", "pyramid_of", "load_pyramid_for_view", "visible_box",
           "plan_region", "read_region"]

#: Bytes of the level the window opens a large pyramid at.
COARSE_BUDGET = 128 << 20
#: Bytes of the region of a finer level read when zoomed in.
REGION_BUDGET = 128 << 20


@dataclass(frozen=True)
class RegionPlan:
    """A region of one pyramid level: ``start``/``stop`` sample indices ``(z, y, x)`` of level ``level``."""

    level: int
    start: tuple[int, int, int]
    stop: tuple[int, int, int]

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(b - a for a, b in zip(self.start, self.stop))

    def nbytes(self, itemsize: int) -> int:
        return int(np.prod(self.shape)) * int(itemsize)

    def covers(self, other: "RegionPlan | None") -> bool:
        """Whether this region already shows ``other`` (same level, ``other`` inside it): no need to read again."""
        return (other is not None and other.level == self.level
                and all(a <= c and d <= b for a, b, c, d in zip(self.start, self.stop, other.start, other.stop)))


def pyramid_of(volume: Volume | None):
    """The :class:`~app.io.zarr.ChunkedVolume` a coarse or region volume was read from (metadata only), or None
    for any other volume."""
    info = (volume.metadata.get("pyramid") if volume is not None else None) or {}
    if not info.get("path"):
        return None

    return open_zarr(info["path"])


def load_pyramid_for_view(path, *, series_uid: str | None = None, labels: bool | None = None,
                          budget: int | None = None, progress: ProgressCallback = None) -> Volume:
    """Read the finest level of the store at ``path`` that fits ``budget`` bytes (default :data:`COARSE_BUDGET`),
    with the value range, robust range and histogram the workbench shows computed from that level (level 0 when it
    fits: nothing to refine). ``labels`` as :func:`app.workbench.mark_labels`; ``series_uid`` is ignored (Zarr
    stores hold one volume); the signature is :func:`app.workbench.load_for_workbench`'s."""
    from .workbench import mark_labels

    chunked = open_zarr(path)
    level = chunked.coarsest_fitting(int(COARSE_BUDGET if budget is None else budget))
    volume = _read(chunked, level, ((0, 0, 0), chunked.levels[level].shape), progress)
    volume.metadata["level"] = level
    volume.metadata["levels"] = len(chunked.levels)
    if level > 0:
        lv = chunked.levels[level]
        volume.metadata["pyramid"] = {"path": str(chunked.path), "level": level, "levels": len(chunked.levels)}
        volume.metadata.setdefault("warnings", []).append(
            f"{chunked.path.name}: opened pyramid level {level} ({'x'.join(map(str, lv.dimensions))} voxels, "
            f"{' x '.join(f'{s:g}' for s in lv.spacing)} mm) of {len(chunked.levels)}; the 3D views read finer "
            f"levels of the region in view when zoomed in (full resolution: {chunked.nbytes(0) / 2**30:.1f} GiB)")
    volume.value_range
    volume.percentile_range()
    volume.histogram()
    mark_labels(volume, labels)
    report(progress, 1.0)
    return volume


# -- what is in view ------------------------------------------------------------------------------------------------
def _frustum(camera: Camera, aspect: float):
    """Planes ``(normals (4, 3), offsets (4,))`` with inside ``n . p >= d``, and the four corner rays."""
    right, up, forward = camera.basis()
    position = np.asarray(camera.position, float)
    half_w, half_h = camera.half_extents(max(float(aspect), 1e-6), 1.0)
    if camera.parallel_projection:
        normals = np.stack([right, -right, up, -up])
        offsets = normals @ position - np.array([half_w, half_w, half_h, half_h])
        origins = np.stack([position + sx * half_w * right + sy * half_h * up
                            for sx in (-1, 1) for sy in (-1, 1)])
        directions = np.tile(forward, (4, 1))
    else:
        normals = np.stack([right + half_w * forward, -right + half_w * forward, up + half_h * forward,
                            -up + half_h * forward])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        offsets = normals @ position
        origins = np.tile(position, (4, 1))
        directions = np.stack([forward + sx * half_w * right + sy * half_h * up for sx in (-1, 1) for sy in (-1, 1)])
    return normals, offsets, origins, directions


def visible_box(camera: Camera, aspect: float, box_min, box_max) -> tuple[np.ndarray, np.ndarray] | None:
    """Axis-aligned bounds ``(lo, hi)`` of the part of the box ``[box_min, box_max]`` (same frame as the camera)
    inside the view frustum of ``camera`` with viewport ``aspect`` = width / height; None when none of it is."""
    lo, hi = np.asarray(box_min, float), np.asarray(box_max, float)
    normals, offsets, origins, directions = _frustum(camera, aspect)
    scale = float(np.max(hi - lo)) or 1.0
    tolerance = 1e-9 * scale

    def inside(points):
        return np.all(points @ normals.T >= offsets - tolerance, axis=1)

    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    candidates = [corners[inside(corners)]]
    # Box edges crossing the frustum planes.
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.count_nonzero(corners[a] != corners[b]) == 1]
    starts = np.array([corners[a] for a, _ in edges])
    vectors = np.array([corners[b] - corners[a] for a, b in edges])
    for normal, offset in zip(normals, offsets):
        denominator = vectors @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (offset - starts @ normal) / denominator
        ok = (np.abs(denominator) > 1e-15) & (t >= 0) & (t <= 1)
        points = starts[ok] + t[ok, None] * vectors[ok]
        candidates.append(points[inside(points)])
    # The frustum's corner rays crossing the box (entry and exit).
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - origins) / directions
        t1 = (hi - origins) / directions
    t0 = np.where(directions == 0, np.where((origins >= lo) & (origins <= hi), -np.inf, np.inf), t0)
    t1 = np.where(directions == 0, np.where((origins >= lo) & (origins <= hi), np.inf, -np.inf), t1)
    entry = np.maximum(np.minimum(t0, t1).max(axis=1), 0.0)
    exit_ = np.maximum(t0, t1).min(axis=1)
    hit = exit_ >= entry
    for t in (entry, exit_):
        candidates.append(origins[hit] + t[hit, None] * directions[hit])
    points = np.concatenate(candidates)
    points = points[np.all(np.isfinite(points), axis=1)]
    if points.shape[0] == 0:
        return None
    return np.clip(points.min(axis=0), lo, hi), np.clip(points.max(axis=0), lo, hi)


def _level_geometry(chunked, level: int) -> Volume:
    lv = chunked.levels[level]
    return Volume(np.zeros((1, 1, 1), np.uint8), lv.spacing, lv.origin, chunked.direction)


def plan_region(chunked, camera: Camera, aspect: float, *, coarse_level: int,
                budget: int | None = None) -> RegionPlan | None:
    """The finest level and region of ``chunked`` to show for ``camera`` (world LPS mm) with viewport ``aspect``,
    or None when the coarse level on show is as good as ``budget`` bytes (default :data:`REGION_BUDGET`) allow
    (or nothing is in view)."""
    budget = REGION_BUDGET if budget is None else int(budget)
    base = _level_geometry(chunked, 0)
    nx, ny, nz = chunked.dimensions
    box_max = (np.array([nx, ny, nz], float) - 1) * np.asarray(base.spacing)
    local = camera.transformed(np.linalg.inv(base.local_to_world))
    box = visible_box(local, aspect, np.zeros(3), box_max)
    if box is None:
        return None
    lo, hi = box
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    world = corners @ base.direction.T + np.asarray(base.origin)
    itemsize = chunked.dtype.itemsize
    for level in range(min(coarse_level, len(chunked.levels))):
        shape = chunked.levels[level].shape
        ijk = _level_geometry(chunked, level).world_to_index(world)
        start = np.maximum(np.floor(ijk.min(axis=0)) - 1, 0).astype(int)[::-1]
        stop = np.minimum(np.ceil(ijk.max(axis=0)) + 2, np.asarray(shape[::-1])).astype(int)[::-1]
        if np.any(stop <= start):
            return None
        plan = RegionPlan(level, tuple(int(s) for s in start), tuple(int(s) for s in stop))
        if plan.nbytes(itemsize) <= budget:
            return plan
    return None


# -- reading --------------------------------------------------------------------------------------------------------
def _read(chunked, level: int, bounds, progress: ProgressCallback) -> Volume:
    start, stop = (np.asarray(b, int) for b in bounds)
    lv = chunked.levels[level]
    array = np.empty(tuple(stop - start), chunked.dtype)
    zarr_array = chunked.zarr_array(level)
    step = max(int(lv.chunks[0]), 1)  # one row of chunks along z per slab (progress and cancel between slabs)
    edges = [int(start[0]), *range((int(start[0]) // step + 1) * step, int(stop[0]), step), int(stop[0])]
    for n, (z0, z1) in enumerate(zip(edges[:-1], edges[1:])):
        array[z0 - start[0]:z1 - start[0]] = zarr_array[z0:z1, start[1]:stop[1], start[2]:stop[2]]
        report(progress, 0.9 * (n + 1) / (len(edges) - 1))
    geometry = _level_geometry(chunked, level)
    origin = geometry.index_to_world(start[::-1].astype(float))
    metadata = {**chunked.metadata, "source_path": str(chunked.path), "level": level,
                "levels": len(chunked.levels)}
    metadata["warnings"] = list(metadata.get("warnings", []))
    return Volume(array, lv.spacing, tuple(origin), chunked.direction, chunked.modality, chunked.units, metadata)


def read_region(chunked, plan: RegionPlan, *, value_range: tuple[float, float] | None = None,
                budget: int | None = None, progress: ProgressCallback = None) -> Volume:
    """Read ``plan``'s region into a :class:`Volume` at its true place (origin of its first sample, the level's
    spacing, the volume's direction); ``value_range``: the range transfer functions use (the coarse volume's).
    A region over ``budget`` bytes is refused (one line). ``progress`` may raise ``OperationCancelled`` between
    slabs."""
    size = plan.nbytes(chunked.dtype.itemsize)
    budget = REGION_BUDGET if budget is None else int(budget)
    if size > budget:
        raise ValueError(f"{chunked.path.name}: the region of level {plan.level} needs {size / 2**30:.2f} GiB, more "
                         f"than the {budget / 2**30:.2f} GiB a view may read; zoom in further")
    started = time.perf_counter()
    volume = _read(chunked, plan.level, (plan.start, plan.stop), progress)
    volume.metadata["read_seconds"] = time.perf_counter() - started
    volume.metadata["pyramid"] = {"path": str(chunked.path), "level": plan.level, "levels": len(chunked.levels),
                                  "region": [list(plan.start), list(plan.stop)]}
    if value_range is not None:
        volume.assume_value_range(*value_range)
    report(progress, 1.0)
    return volume

