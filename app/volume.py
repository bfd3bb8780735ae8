"""The volume model: scalars plus the geometry that places them in the patient.

Axis order (stated once, used everywhere)
-----------------------------------------
``Volume.array`` has shape ``(nz, ny, nx)`` and is indexed ``array[k, j, i]``; ``i`` varies fastest in memory.
Spacing and origin are given in ``(i, j, k)`` = ``(x, y, z)`` order, in millimetres. ``array.ravel()`` is VTK's
point order, so conversion to ``vtkImageData`` never transposes.

Geometry
--------
The world (patient) position in LPS millimetres of voxel ``(i, j, k)`` is::

    p = origin + direction @ (spacing * (i, j, k))

``direction`` is a 3x3 matrix whose *columns* are the unit LPS directions of the ``i``, ``j`` and ``k`` axes (the
DICOM ImageOrientationPatient row and column cosines and the slice normal). NIfTI files are RAS and are converted
on reading (x and y negated).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from algorithms.common.grid import Grid
from algorithms.common.vtk_bridge import array_from_image, image_from_array

#: Anatomical names of the LPS axes, for labels: (negative end, positive end) per axis.
LPS_AXIS_LABELS = (("R", "L"), ("A", "P"), ("I", "S"))
#: The matrix that converts LPS coordinates to RAS and back (it is its own inverse).
LPS_TO_RAS = np.diag([-1.0, -1.0, 1.0])


def _as_direction(direction) -> np.ndarray:
    matrix = np.asarray(direction, dtype=np.float64).reshape(3, 3)
    if not np.allclose(matrix.T @ matrix, np.eye(3), atol=1e-4):
        raise ValueError(f"the direction matrix must be orthonormal, got {matrix.tolist()}")
    return matrix


@dataclass
class Volume:
    """A scalar volume with spacing, origin and direction in LPS millimetres.

    Parameters
    ----------
    array : ndarray, shape (nz, ny, nx)
        Scalar values, indexed ``[k, j, i]``.
    spacing : (sx, sy, sz)
        Voxel size in mm along i, j, k.
    origin : (x, y, z)
        LPS position in mm of the centre of voxel (0, 0, 0).
    direction : ndarray (3, 3)
        Columns are the LPS unit directions of the i, j, k axes.
    modality : str
        "CT", "MR", ... or "" when unknown.
    units : str
        Units of the values: "HU" for CT, "" (arbitrary) otherwise.
    metadata : dict
        Source information: ``source_format``, ``source_path``, series UID, warnings, ignored files...
    """

    array: np.ndarray
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: np.ndarray = field(default_factory=lambda: np.eye(3))
    modality: str = ""
    units: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        array = np.asarray(self.array)
        if array.ndim != 3:
            raise ValueError(f"a volume needs a 3D array (nz, ny, nx), got shape {array.shape}")
        if array.size == 0:
            raise ValueError("the volume is empty")
        if array.dtype == np.bool_:
            array = array.astype(np.uint8)
        if array.dtype.kind not in "iuf":
            raise ValueError(f"unsupported scalar type {array.dtype}")
        if not array.dtype.isnative:  # big-endian files: compute in the machine's byte order
            array = array.astype(array.dtype.newbyteorder("="))
        spacing = tuple(float(s) for s in self.spacing)
        if len(spacing) != 3 or not all(np.isfinite(spacing)) or min(spacing) <= 0:
            raise ValueError(f"spacing must be three positive millimetre values, got {self.spacing!r}")
        origin = tuple(float(o) for o in self.origin)
        if len(origin) != 3 or not all(np.isfinite(origin)):
            raise ValueError(f"origin must be three finite millimetre values, got {self.origin!r}")
        self.array = array
        self.spacing = spacing
        self.origin = origin
        self.direction = _as_direction(self.direction)
        self.metadata = dict(self.metadata)
        self._range: tuple[float, float] | None = None
        self._percentiles: dict[tuple[float, float], tuple[float, float]] = {}
        self._histograms: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    # -- sizes and values --------------------------------------------------------------------------------------
    @property
    def dimensions(self) -> tuple[int, int, int]:
        """``(nx, ny, nz)``: voxels along i, j, k (VTK order)."""
        nz, ny, nx = self.array.shape
        return nx, ny, nz

    @property
    def value_range(self) -> tuple[float, float]:
        """Minimum and maximum value (computed once, finite values only)."""
        if self._range is None:
            data = self.array
            if data.dtype.kind == "f" and not np.all(np.isfinite(data)):
                data = data[np.isfinite(data)]
                if data.size == 0:
                    raise ValueError("the volume has no finite values")
            self._range = (float(data.min()), float(data.max()))
        return self._range

    def assume_value_range(self, low: float, high: float) -> None:
        """Use ``(low, high)`` as the value range (a region of a larger volume keeps the whole volume's range, so
        transfer functions map values to the same colours)."""
        if not (np.isfinite(low) and np.isfinite(high) and low <= high):
            raise ValueError(f"a value range needs finite low <= high, got {low!r}, {high!r}")
        self._range = (float(low), float(high))

    def percentile_range(self, low: float = 0.5, high: float = 99.5, *, max_samples: int = 1_000_000):
        """Robust value range: the ``low`` and ``high`` percentiles (a regular subsample of large volumes; cached)."""
        key = (float(low), float(high))
        if key not in self._percentiles:
            flat = self.array.ravel()
            if flat.size > max_samples:
                flat = flat[:: flat.size // max_samples + 1]
            if flat.dtype.kind == "f":
                flat = flat[np.isfinite(flat)]
            lo, hi = (float(v) for v in np.percentile(flat, [low, high]))
            if hi <= lo:
                lo, hi = self.value_range
            self._percentiles[key] = (lo, hi if hi > lo else lo + 1.0)
        return self._percentiles[key]

    def histogram(self, bins: int = 256, *, max_samples: int = 4_000_000) -> tuple[np.ndarray, np.ndarray]:
        """Counts and edges over the full value range (a regular subsample of large volumes; cached)."""
        if bins not in self._histograms:
            lo, hi = self.value_range
            data = self.array.ravel()
            if data.size > max_samples:
                data = data[:: data.size // max_samples + 1]
            self._histograms[bins] = np.histogram(data, bins=bins, range=(lo, hi if hi > lo else lo + 1.0))
        return self._histograms[bins]

    @property
    def units_label(self) -> str:
        """Units for display, e.g. "HU" or "a.u." (arbitrary units) when the scanner gives none."""
        return self.units or "a.u."

    # -- geometry ------------------------------------------------------------------------------------------
    @property
    def affine(self) -> np.ndarray:
        """4x4 matrix taking homogeneous index ``(i, j, k, 1)`` to LPS mm."""
        matrix = np.eye(4)
        matrix[:3, :3] = self.direction * np.asarray(self.spacing)[None, :]
        matrix[:3, 3] = self.origin
        return matrix

    @property
    def local_to_world(self) -> np.ndarray:
        """4x4 rigid matrix taking the *volume frame* (index times spacing, in mm) to LPS mm.

        VTK views place an identity-direction image at the volume frame and give its prop this matrix, so every
        mapper (including those that ignore an image's direction) shows the volume where it belongs.
        """
        matrix = np.eye(4)
        matrix[:3, :3] = self.direction
        matrix[:3, 3] = self.origin
        return matrix

    def index_to_world(self, ijk) -> np.ndarray:
        """LPS mm of index coordinates ``(..., 3)`` given as ``(i, j, k)``."""
        ijk = np.asarray(ijk, dtype=np.float64)
        return ijk * np.asarray(self.spacing) @ self.direction.T + np.asarray(self.origin)

    def world_to_index(self, points) -> np.ndarray:
        """Continuous ``(i, j, k)`` of LPS points ``(..., 3)``."""
        points = np.asarray(points, dtype=np.float64) - np.asarray(self.origin)
        return points @ self.direction / np.asarray(self.spacing)

    @property
    def extent_mm(self) -> tuple[float, float, float]:
        """Distance in mm between the first and last voxel centre along i, j, k."""
        return tuple(float((n - 1) * s) for n, s in zip(self.dimensions, self.spacing))

    @property
    def world_corners(self) -> np.ndarray:
        """The 8 corner voxel centres in LPS mm, ``(8, 3)``."""
        nx, ny, nz = self.dimensions
        corners = np.array([[i, j, k] for k in (0, nz - 1) for j in (0, ny - 1) for i in (0, nx - 1)], float)
        return self.index_to_world(corners)

    @property
    def world_bounds(self) -> tuple[float, float, float, float, float, float]:
        """Axis-aligned LPS bounds ``(xmin, xmax, ymin, ymax, zmin, zmax)`` of the voxel centres, in mm."""
        corners = self.world_corners
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        return (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), float(lo[2]), float(hi[2]))

    @property
    def centre(self) -> np.ndarray:
        """LPS position of the volume centre (mm)."""
        return self.index_to_world((np.asarray(self.dimensions) - 1) / 2.0)

    def axis_labels(self) -> list[str]:
        """For each of i, j, k, the anatomical direction it points to most, e.g. ``['L', 'P', 'S']``."""
        labels = []
        for column in self.direction.T:
            axis = int(np.argmax(np.abs(column)))
            labels.append(LPS_AXIS_LABELS[axis][1 if column[axis] > 0 else 0])
        return labels

    # -- conversion -------------------------------------------------------------------------------------------
    def to_vtk(self, *, local: bool = False, name: str = "scalars"):
        """A ``vtkImageData`` of the volume.

        With ``local=False`` the image carries origin and direction (VTK >= 9 honours them in filters). With
        ``local=True`` it sits in the volume frame (origin 0, identity direction); combine it with
        :attr:`local_to_world` as a prop's user matrix for rendering.

        The image shares the volume's memory (no copy: a 512^3 int16 volume is not held twice). So that nothing
        writes through it unnoticed, :attr:`array` becomes a read-only view of the same memory here (a volume's
        values never change in place: derived data are new volumes; the caller's own array object is left as it
        was), and our filters read VTK's scalars as read-only views. A non-contiguous array is copied once instead.
        """
        if self.array.flags.c_contiguous and self.array.flags.writeable:
            self.array = self.array.view()
            self.array.flags.writeable = False
        image = image_from_array(self.array, self.spacing, (0.0, 0.0, 0.0) if local else self.origin, name,
                                 share=True)
        if not local:
            image.SetDirectionMatrix(*self.direction.ravel())
        return image

    def to_pyvista(self, *, local: bool = False, name: str = "scalars"):
        """The same as :meth:`to_vtk` wrapped as a ``pyvista.ImageData`` (shares memory with the VTK object)."""
        import pyvista

        return pyvista.wrap(self.to_vtk(local=local, name=name))

    @classmethod
    def from_vtk(cls, image, *, modality: str = "", units: str = "", metadata: dict | None = None) -> "Volume":
        """A volume from a ``vtkImageData`` or ``pyvista.ImageData`` (point scalars; origin, spacing, direction)."""
        array = np.array(array_from_image(image), copy=True)
        direction = np.array([image.GetDirectionMatrix().GetElement(r, c) for r in range(3) for c in range(3)])
        return cls(
            array,
            spacing=image.GetSpacing(),
            origin=image.GetOrigin(),
            direction=direction.reshape(3, 3),
            modality=modality,
            units=units,
            metadata=metadata or {},
        )

    def with_array(self, array: np.ndarray, **changes) -> "Volume":
        """A copy of the geometry and metadata around a new array of the same shape."""
        if np.shape(array) != self.array.shape:
            raise ValueError(f"new array shape {np.shape(array)} differs from {self.array.shape}")
        values = dict(
            spacing=self.spacing, origin=self.origin, direction=self.direction, modality=self.modality,
            units=self.units, metadata=dict(self.metadata),
        )
        values.update(changes)
        return Volume(array, **values)

    @property
    def grid(self):
        """The volume's :class:`~algorithms.common.grid.Grid` (dimensions, spacing, origin, direction)."""
        return Grid(self.dimensions, self.spacing, self.origin, tuple(self.direction.ravel()))

    @classmethod
    def on_grid(cls, array: np.ndarray, grid, **values) -> "Volume":
        """A volume holding ``array`` (shape ``grid.shape``) on ``grid``."""
        if np.shape(array) != grid.shape:
            raise ValueError(f"an array of shape {np.shape(array)} does not fit a grid of shape {grid.shape}")
        return cls(array, spacing=grid.spacing, origin=grid.origin, direction=grid.direction_matrix, **values)

    def resampled(self, grid, *, order: int = 1, fill: float | None = None, progress=None) -> "Volume":
        """The volume sampled at the voxel centres of another ``grid`` (any spacing, origin, direction).

        ``order`` 1 interpolates trilinearly (continuous values), 0 takes the nearest voxel (labels and masks).
        Points outside the volume get ``fill`` (default: the volume's minimum). The values keep their type for
        ``order=0``; trilinear results are float32 unless the volume holds integers and ``order=0``. Works one
        output slice at a time, so memory stays near the output's size.
        """
        from scipy import ndimage

        if order not in (0, 1):
            raise ValueError(f"resampling order must be 0 (nearest) or 1 (trilinear), got {order}")
        fill = float(self.value_range[0]) if fill is None else float(fill)
        dtype = self.array.dtype if order == 0 else np.float32
        output = np.empty(grid.shape, dtype=dtype)
        nx, ny, nz = grid.dimensions
        j, i = np.mgrid[0:ny, 0:nx]
        source = self.array if order == 0 else self.array.astype(np.float32, copy=False)
        for k in range(nz):
            ijk = np.stack([i.ravel(), j.ravel(), np.full(i.size, k)], axis=1)
            index = self.world_to_index(grid.index_to_world(ijk))
            coordinates = index[:, ::-1].T  # (k, j, i) rows for the (nz, ny, nx) array
            output[k] = ndimage.map_coordinates(source, coordinates, order=order, mode="constant", cval=fill,
                                                prefilter=False).reshape(ny, nx)
            if progress is not None:
                progress((k + 1) / nz)
        return Volume.on_grid(output, grid, modality=self.modality, units=self.units,
                              metadata={**self.metadata, "resampled_from": self.grid.describe()})

    def crop(self, i: tuple[int, int], j: tuple[int, int], k: tuple[int, int]) -> "Volume":
        """The voxels ``i[0] <= i < i[1]`` (and likewise j, k) as a volume at the same place in the patient."""
        bounds = []
        for name, (lo, hi), size in zip("ijk", (i, j, k), self.dimensions):
            if not 0 <= lo < hi <= size:
                raise ValueError(f"crop range {name} = {lo}..{hi} must lie within 0..{size} and not be empty")
            bounds.append((int(lo), int(hi)))
        (i0, i1), (j0, j1), (k0, k1) = bounds
        return Volume(
            np.ascontiguousarray(self.array[k0:k1, j0:j1, i0:i1]), spacing=self.spacing,
            origin=tuple(self.index_to_world((i0, j0, k0))), direction=self.direction, modality=self.modality,
            units=self.units, metadata=dict(self.metadata),
        )

    def padded(self, value, width: int = 1) -> "Volume":
        """The volume surrounded by ``width`` layers of ``value`` on every side; every voxel keeps its position.

        The array becomes float32 when ``value`` does not fit its dtype exactly.
        """
        if int(width) != width or width < 1:
            raise ValueError(f"the padding width is a number of voxels, 1 or more; got {width!r}")
        array, value = self.array, float(value)
        if np.issubdtype(array.dtype, np.integer):
            limits = np.iinfo(array.dtype)
            if not (value.is_integer() and limits.min <= value <= limits.max):
                array = array.astype(np.float32)
        elif array.dtype.type(value) != value:
            array = array.astype(np.float32)
        return Volume(
            np.pad(array, int(width), constant_values=array.dtype.type(value)), spacing=self.spacing,
            origin=tuple(self.index_to_world((-width, -width, -width))), direction=self.direction,
            modality=self.modality, units=self.units, metadata=dict(self.metadata),
        )

    def describe(self) -> dict[str, Any]:
        """The facts ``voxelscope info`` prints, JSON-serialisable."""
        lo, hi = self.value_range
        return {
            "dimensions": list(self.dimensions),
            "spacing": [round(s, 6) for s in self.spacing],
            "origin": [round(o, 6) for o in self.origin],
            "direction": [round(float(v), 6) + 0.0 for v in self.direction.ravel()],
            "dtype": str(self.array.dtype),
            "range": [lo, hi],
            "modality": self.modality,
            "units": self.units_label,
            "world_bounds": [round(b, 6) for b in self.world_bounds],
            "source_format": self.metadata.get("source_format", ""),
            "warnings": list(self.metadata.get("warnings", [])),
        }


def right_handed(volume: Volume) -> Volume:
    """The same volume stored with a right-handed index frame (det(direction) = +1).

    NIfTI files are often stored left-handed (radiological order). Renderers and mesh orientation assume a
    right-handed frame, so the i axis is reversed (array flipped, origin moved to the other end, direction column
    negated): every voxel keeps its world position, nothing is resampled.
    """
    if np.linalg.det(volume.direction) > 0:
        return volume
    nx = volume.dimensions[0]
    direction = volume.direction.copy()
    direction[:, 0] *= -1
    origin = volume.index_to_world((nx - 1, 0, 0))
    flipped = Volume(
        np.ascontiguousarray(volume.array[:, :, ::-1]), spacing=volume.spacing, origin=tuple(origin),
        direction=direction, modality=volume.modality, units=volume.units, metadata=dict(volume.metadata),
    )
    flipped.metadata["index_frame"] = "i axis reversed on loading to make the index frame right-handed"
    return flipped


def default_isovalue(units: str, value_range) -> float:
    """The first isovalue of every surface: 300 HU (bone) for CT in HU, else 35 % into ``value_range`` (low, high)."""
    if units == "HU":
        return 300.0
    lo, hi = value_range
    return lo + 0.35 * (hi - lo)


def default_iso(volume: Volume) -> float:
    """:func:`default_isovalue` of a volume in memory, 35 % into its robust (0.5 to 99.5 %) value range."""
    return default_isovalue(volume.units, None if volume.units == "HU" else volume.percentile_range())
