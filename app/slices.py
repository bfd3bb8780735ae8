"""Slice geometry of the workbench, without Qt: the three slice planes through the crosshair, their oblique rotation,
reformatting a volume onto a plane, and the planes' outlines for the 3D views.

Planes and frames
-----------------
Each slice plane has a frame of three LPS unit vectors: ``u`` (screen right), ``v`` (screen up) and the normal
``n = u x v``. The standard frames follow the radiological convention: axial shows the patient's left on the right
and anterior up, coronal the left on the right and superior up, sagittal posterior on the right and superior up.

Oblique reformatting is one rotation ``R`` (3x3) shared by the three planes, as when the crosshair is rotated in
3D Slicer or ITK-SNAP: plane ``p``'s normal is ``R n_p``; its screen axes are the standard ones projected onto the
rotated plane, so the view in which the crosshair is rotated keeps its picture upright while the two other planes
tilt. Rotating in view ``p`` by an angle turns ``R`` about that view's normal.

Reformatting
------------
:func:`plane_grid` lays a pixel grid over the volume's extent on a plane: pixels sit on voxel centres whenever a
screen axis runs along an index axis (so an axis-aligned slice shows exactly the stored voxels, also with linear
interpolation); oblique grids use the smallest voxel spacing. :func:`sample_plane` samples a volume on such a grid
with nearest-neighbour (``order=0``) or trilinear (``order=1``) interpolation (``scipy.ndimage.map_coordinates``);
points outside the voxels' extent are NaN. Image rows run from the top of the screen (largest ``t``) down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PLANES = ("axial", "coronal", "sagittal")
#: plane -> (u, v) in LPS: screen right and screen up of the standard (unrotated) plane.
STANDARD_AXES = {
    "axial": ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0)),
    "coronal": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "sagittal": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
}
#: plane -> the LPS axis its position is read along (z for axial, y for coronal, x for sagittal).
POSITION_AXIS = {"axial": 2, "coronal": 1, "sagittal": 0}
#: 3D Slicer's colours of the three planes (axial red, coronal green, sagittal yellow), RGB in [0, 1].
PLANE_COLORS = {"axial": (0.95, 0.3, 0.3), "coronal": (0.35, 0.85, 0.35), "sagittal": (0.95, 0.85, 0.25)}
MAX_PLANE_PIXELS = 2048 * 2048
_LPS_NAMES = (("R", "L"), ("A", "P"), ("I", "S"))


def _check_plane(plane: str) -> None:
    if plane not in PLANES:
        raise ValueError(f"plane must be one of {', '.join(PLANES)}, got {plane!r}")


def rotation_about(axis, degrees: float) -> np.ndarray:
    """The 3x3 rotation by ``degrees`` about the unit vector ``axis`` (right-hand rule)."""
    axis = np.asarray(axis, dtype=np.float64)
    norm = np.linalg.norm(axis)
    if not np.isfinite(degrees) or norm == 0:
        raise ValueError(f"a rotation needs a finite angle and a non-zero axis, got {degrees} about {axis.tolist()}")
    x, y, z = axis / norm
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) * c + s * k + (1 - c) * np.outer((x, y, z), (x, y, z))


@dataclass(frozen=True)
class PlaneFrame:
    """The LPS frame of one slice plane: ``u`` screen right, ``v`` screen up, ``n = u x v``."""

    plane: str
    u: np.ndarray
    v: np.ndarray
    n: np.ndarray

    @property
    def oblique(self) -> bool:
        """True when the plane is not one of the standard anatomical planes."""
        u, v = (np.asarray(a) for a in STANDARD_AXES[self.plane])
        return not (np.allclose(self.u, u, atol=1e-9) and np.allclose(self.v, v, atol=1e-9))

    def labels(self) -> dict[str, str]:
        """Anatomical letters at the screen's edges: the LPS direction each screen direction points to most."""

        def name(vector) -> str:
            axis = int(np.argmax(np.abs(vector)))
            return _LPS_NAMES[axis][1 if vector[axis] > 0 else 0]

        return {"right": name(self.u), "left": name(-self.u), "top": name(self.v), "bottom": name(-self.v)}


def plane_frame(plane: str, rotation=None) -> PlaneFrame:
    """The frame of ``plane`` under the shared oblique ``rotation`` (3x3; None for the standard planes)."""
    _check_plane(plane)
    u0, v0 = (np.asarray(a, dtype=np.float64) for a in STANDARD_AXES[plane])
    rotation = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    n = rotation @ np.cross(u0, v0)
    u = u0 - (u0 @ n) * n
    if np.linalg.norm(u) < 1e-3:  # the screen-right axis became the normal: follow the rotation instead
        u = rotation @ u0
    u = u / np.linalg.norm(u)
    v = np.cross(n, u)
    return PlaneFrame(plane, u, v / np.linalg.norm(v), n)


def slice_frames(rotation=None) -> dict[str, PlaneFrame]:
    return {plane: plane_frame(plane, rotation) for plane in PLANES}


def crosshair_lines(plane: str, rotation=None) -> dict[str, tuple[float, float]]:
    """In ``plane``'s screen axes (u, v), the unit direction of each other plane's intersection line with it."""
    frames = slice_frames(rotation)
    this = frames[plane]
    lines = {}
    for other, frame in frames.items():
        if other == plane:
            continue
        direction = np.cross(this.n, frame.n)
        length = np.linalg.norm(direction)
        if length < 1e-9:
            continue
        direction /= length
        lines[other] = (float(direction @ this.u), float(direction @ this.v))
    return lines


@dataclass(frozen=True)
class PlaneGrid:
    """A pixel grid on a plane: pixel ``(row, column)`` is at ``origin + s u + t v`` with
    ``s = s0 + column * ds`` and ``t = t0 - row * dt`` (row 0 at the top of the screen)."""

    frame: PlaneFrame
    origin: np.ndarray  # LPS point of s = t = 0 (the volume centre projected onto the plane)
    s0: float
    t0: float
    ds: float
    dt: float
    rows: int
    columns: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.columns

    def points(self) -> np.ndarray:
        """LPS positions of every pixel centre, ``(rows, columns, 3)``."""
        s = self.s0 + np.arange(self.columns) * self.ds
        t = self.t0 - np.arange(self.rows) * self.dt
        return (self.origin + s[None, :, None] * self.frame.u + t[:, None, None] * self.frame.v)

    def to_plane(self, points) -> np.ndarray:
        """``(s, t)`` plane coordinates (mm) of LPS points ``(..., 3)`` (their projection onto the plane)."""
        d = np.asarray(points, dtype=np.float64) - self.origin
        return np.stack([d @ self.frame.u, d @ self.frame.v], axis=-1)

    def to_world(self, s, t) -> np.ndarray:
        return self.origin + np.multiply.outer(s, self.frame.u) + np.multiply.outer(t, self.frame.v)

    def pixel_of(self, s, t) -> tuple[float, float]:
        """Continuous ``(column, row)`` of plane coordinates (pixel centres at whole numbers)."""
        return (s - self.s0) / self.ds, (self.t0 - t) / self.dt

    def plane_of(self, column, row) -> tuple[float, float]:
        return self.s0 + column * self.ds, self.t0 - row * self.dt

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(s_min, s_max, t_min, t_max)`` of the image's edges (half a pixel beyond the outer centres), mm."""
        return (self.s0 - self.ds / 2, self.s0 + (self.columns - 0.5) * self.ds,
                self.t0 - (self.rows - 0.5) * self.dt, self.t0 + self.dt / 2)


def _step_along(volume, axis: np.ndarray) -> float | None:
    """The voxel spacing along ``axis`` when it runs along an index axis of ``volume``, else None."""
    cosines = volume.direction.T @ axis
    index = int(np.argmax(np.abs(cosines)))
    return float(volume.spacing[index]) if abs(cosines[index]) > 1 - 1e-6 else None


def voxel_aligned(volume, frame: PlaneFrame) -> bool:
    """True when both screen axes of ``frame`` run along index axes of ``volume`` (its pixels are voxels)."""
    return _step_along(volume, frame.u) is not None and _step_along(volume, frame.v) is not None


def plane_grid(volume, frame: PlaneFrame, cursor) -> PlaneGrid:
    """The pixel grid covering ``volume`` on the plane of ``frame`` through ``cursor`` (LPS mm)."""
    cursor = np.asarray(cursor, dtype=np.float64)
    centre = volume.centre
    origin = centre + ((cursor - centre) @ frame.n) * frame.n
    corners = volume.world_corners - origin
    s, t = corners @ frame.u, corners @ frame.v
    finest = float(min(volume.spacing))
    ds = _step_along(volume, frame.u) or finest
    dt = _step_along(volume, frame.v) or finest
    columns = int(round((s.max() - s.min()) / ds)) + 1
    rows = int(round((t.max() - t.min()) / dt)) + 1
    if rows * columns > MAX_PLANE_PIXELS:  # very large slices: coarser pixels, never a runaway allocation
        factor = float(np.sqrt(rows * columns / MAX_PLANE_PIXELS))
        ds, dt = ds * factor, dt * factor
        columns = int(np.floor((s.max() - s.min()) / ds)) + 1
        rows = int(np.floor((t.max() - t.min()) / dt)) + 1
    return PlaneGrid(frame, origin, float(s.min()), float(t.max()), ds, dt, rows, columns)


def sample_plane(volume, grid: PlaneGrid, *, order: int = 1) -> np.ndarray:
    """``volume`` sampled at the pixel centres of ``grid``, ``(rows, columns)`` float32, NaN outside the voxels.

    ``order`` 1 interpolates trilinearly, 0 takes the nearest voxel (labels, masks, or by choice).
    """
    from scipy import ndimage

    if order not in (0, 1):
        raise ValueError(f"interpolation order must be 0 (nearest) or 1 (linear), got {order}")
    index = volume.world_to_index(grid.points()).reshape(-1, 3)
    dims = np.asarray(volume.dimensions, dtype=np.float64)
    tolerance = 1e-6
    inside = np.all((index >= -0.5 - tolerance) & (index <= dims - 0.5 + tolerance), axis=1)
    if order == 1:  # between the outer voxel centres and the voxels' edges: the edge value
        index = np.clip(index, 0.0, dims - 1)
    source = volume.array
    if order == 1 and source.dtype != np.float32:
        source = source.astype(np.float32)
    values = ndimage.map_coordinates(source, index[:, ::-1].T, order=order, mode="nearest", prefilter=False,
                                     output=np.float32)
    values[~inside] = np.nan
    return values.reshape(grid.shape)


def value_at(volume, point, *, order: int = 0) -> float | None:
    """The volume's value at an LPS point (nearest voxel or trilinear), None outside its voxels."""
    index = volume.world_to_index(point)
    dims = np.asarray(volume.dimensions)
    if np.any(index < -0.5) or np.any(index > dims - 0.5):
        return None
    if order == 0:
        i, j, k = np.clip(np.rint(index).astype(int), 0, dims - 1)
        return float(volume.array[k, j, i])
    from scipy import ndimage

    index = np.clip(index, 0, dims - 1)
    return float(ndimage.map_coordinates(volume.array.astype(np.float32, copy=False), index[::-1, None], order=1,
                                         mode="nearest")[0])


def plane_outline(volume, frame: PlaneFrame, cursor) -> np.ndarray:
    """Where the plane through ``cursor`` cuts the box of the volume's voxel centres: polygon corners ``(m, 3)``
    in LPS, ordered around the plane (empty when the plane misses the box)."""
    corners = volume.world_corners  # index order: bit 0 = i, bit 1 = j, bit 2 = k
    distance = (corners - np.asarray(cursor, dtype=np.float64)) @ frame.n
    points = []
    for a in range(8):
        for bit in (1, 2, 4):
            b = a | bit
            if b == a:
                continue
            da, db = distance[a], distance[b]
            if abs(da) < 1e-9:
                points.append(corners[a])
            elif da * db < 0:
                points.append(corners[a] + (corners[b] - corners[a]) * (da / (da - db)))
    if len(points) < 3:
        return np.zeros((0, 3))
    points = np.unique(np.round(np.array(points), 9), axis=0)
    centre = points.mean(axis=0)
    angles = np.arctan2((points - centre) @ frame.v, (points - centre) @ frame.u)
    return points[np.argsort(angles)]


def plane_outlines_polydata(volume, cursor, rotation=None) -> dict:
    """The three planes' outlines as closed ``vtkPolyData`` polylines (LPS mm), by plane name."""
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    result = {}
    for plane, frame in slice_frames(rotation).items():
        corners = plane_outline(volume, frame, cursor)
        points, lines = vtkPoints(), vtkCellArray()
        for corner in corners:
            points.InsertNextPoint(*corner)
        if len(corners):
            lines.InsertNextCell(len(corners) + 1)
            for index in list(range(len(corners))) + [0]:
                lines.InsertCellPoint(index)
        polydata = vtkPolyData()
        polydata.SetPoints(points)
        polydata.SetLines(lines)
        result[plane] = polydata
    return result


def polyline_polydata(points) -> "object":
    """An open polyline through ``points`` ``(m, 3)`` (LPS mm) as ``vtkPolyData`` (measurements in 3D views)."""
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    vtk_points, lines = vtkPoints(), vtkCellArray()
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    for point in points:
        vtk_points.InsertNextPoint(*point)
    lines.InsertNextCell(len(points))
    for index in range(len(points)):
        lines.InsertCellPoint(index)
    polydata = vtkPolyData()
    polydata.SetPoints(vtk_points)
    polydata.SetLines(lines)
    return polydata
