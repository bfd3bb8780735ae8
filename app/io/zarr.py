"""Chunked volumes: reading and writing Zarr v2/v3 and OME-Zarr (multiscale pyramids) without loading them whole.

Format
------
OME-Zarr (OME-NGFF 0.4 on Zarr v2, 0.5 on Zarr v3): a Zarr group whose ``multiscales`` metadata lists the
resolution levels (``datasets``, finest first), each with ``coordinateTransformations`` (a ``scale`` and a
``translation``, slowest axis first) and the ``axes`` (``z``, ``y``, ``x``, type ``space``, unit ``millimeter``).

Axes and patient coordinates
----------------------------
Arrays are stored ``(z, y, x)`` = our ``(k, j, i)`` (:mod:`app.volume`'s order, ``i`` fastest), so no transpose.
OME-NGFF has no patient orientation; Voxelscope takes the OME physical space as LPS millimetres: the position of
sample ``(z, y, x)`` of level ``n`` is ``translation_n + scale_n * (z, y, x)``, with ``x`` towards patient left,
``y`` towards posterior, ``z`` towards superior (the DICOM/ITK convention). A volume whose direction is not the
identity keeps its 3x3 direction in the group's ``voxelscope`` attributes (columns: LPS directions of i, j, k,
rotating about the origin); other readers (napari, neuroglancer) then show it unrotated. A plain Zarr array (no
OME metadata) is read with 1 mm spacing unless ``voxelscope`` attributes give its geometry.

Pyramid
-------
Level ``n`` is the mean of 2x2x2 blocks of level ``n - 1`` (odd trailing samples dropped), so its samples are the
centres of those blocks: ``scale_n = 2**n * scale_0`` and ``translation_n = origin + (2**n - 1) / 2 * scale_0``.
Each level is computed from the stored level above it, chunk by chunk, so writing never holds a whole level.
Alongside the levels a small array ``chunk_range`` holds the minimum and maximum of every chunk of level 0:
chunked meshing skips the chunks the surface cannot cross without reading them.

References
----------
J. Moore et al., "OME-NGFF: a next-generation file format for expanding bioimaging data-access strategies",
Nature Methods 18, 1496-1498, 2021 (specification versions 0.4 and 0.5, https://ngff.openmicroscopy.org/).
"""

from __future__ import annotations

import json
import os
import shutil
import uuid
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..volume import Volume
from .errors import CorruptFileError, FileExistsRefusal, UnsupportedFormatError, VolumeReadError, VolumeWriteError

__all__ = ["ChunkedVolume", "Level", "COMPRESSORS", "DEFAULT_BUDGET", "is_zarr_path", "open_zarr", "read_zarr",
           "write_ome_zarr", "save_zarr"]

#: Bytes an in-memory read of one level may take (the window and the eager readers refuse more).
DEFAULT_BUDGET = 1 << 30
COMPRESSORS = ("blosc-zstd", "blosc-lz4", "zstd", "none")
_MARKERS = (".zgroup", ".zarray", "zarr.json")


def is_zarr_path(path) -> bool:
    """Whether ``path`` names a Zarr store: a folder ending in ``.zarr`` or holding Zarr metadata."""
    path = Path(path)
    if path.name.lower().endswith(".zarr"):
        return True
    return path.is_dir() and any((path / marker).is_file() for marker in _MARKERS)


@dataclass(frozen=True)
class Level:
    """One resolution level: its array path in the group, shape ``(nz, ny, nx)``, chunks, and geometry
    (``spacing`` and ``origin`` as ``(x, y, z)`` mm)."""

    name: str
    shape: tuple[int, int, int]
    chunks: tuple[int, int, int]
    spacing: tuple[float, float, float]
    origin: tuple[float, float, float]

    @property
    def dimensions(self) -> tuple[int, int, int]:
        return self.shape[2], self.shape[1], self.shape[0]


@dataclass
class ChunkedVolume:
    """A volume in a Zarr store, read on demand: metadata at once, samples by level or region.

    Attributes
    ----------
    path : Path
        The store (a folder).
    levels : list of Level
        Finest first (level 0 is the full resolution).
    dtype : numpy dtype
    direction : ndarray (3, 3)
        Columns: LPS unit directions of i, j, k.
    """

    path: Path
    levels: list[Level]
    dtype: np.dtype
    direction: np.ndarray = field(default_factory=lambda: np.eye(3))
    modality: str = ""
    units: str = ""
    metadata: dict[str, Any] = field(default_factory=dict)

    # -- metadata -----------------------------------------------------------------------------------------
    @property
    def dimensions(self) -> tuple[int, int, int]:
        return self.levels[0].dimensions

    @property
    def spacing(self) -> tuple[float, float, float]:
        return self.levels[0].spacing

    @property
    def origin(self) -> tuple[float, float, float]:
        return self.levels[0].origin

    @property
    def local_to_world(self) -> np.ndarray:
        """4x4 rigid matrix from the volume frame (index times spacing, mm) to LPS mm (as :class:`Volume`'s)."""
        matrix = np.eye(4)
        matrix[:3, :3] = self.direction
        matrix[:3, 3] = self.origin
        return matrix

    @property
    def units_label(self) -> str:
        return self.units or "a.u."

    def nbytes(self, level: int = 0) -> int:
        return int(np.prod(self.levels[level].shape)) * self.dtype.itemsize

    def coarsest_fitting(self, budget: int = DEFAULT_BUDGET) -> int:
        """The finest level whose samples fit in ``budget`` bytes (the coarsest level if none does)."""
        for n in range(len(self.levels)):
            if self.nbytes(n) <= budget:
                return n
        return len(self.levels) - 1

    def describe(self) -> dict[str, Any]:
        """What ``voxelscope info`` prints, from the metadata alone (no sample is read)."""
        corners = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], float)
        corners *= np.asarray(self.dimensions, float) - 1
        world = corners * np.asarray(self.spacing) @ self.direction.T + np.asarray(self.origin)
        lo, hi = world.min(axis=0), world.max(axis=0)
        value_range = self.metadata.get("value_range")
        return {
            "kind": "volume", "source_format": self.metadata.get("source_format", "Zarr"),
            "dimensions": list(self.dimensions), "spacing": list(self.spacing), "origin": list(self.origin),
            "direction": self.direction.tolist(),
            "world_bounds": [float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), float(lo[2]), float(hi[2])],
            "dtype": str(self.dtype), "range": list(value_range) if value_range else None,
            "modality": self.modality, "units": self.units, "bytes": self.nbytes(0),
            "levels": [{"path": lv.name, "dimensions": list(lv.dimensions), "chunks": list(lv.chunks[::-1]),
                        "spacing": list(lv.spacing)} for lv in self.levels],
            "warnings": list(self.metadata.get("warnings", [])),
        }

    # -- samples ------------------------------------------------------------------------------------------
    def zarr_array(self, level: int = 0):
        import zarr

        return zarr.open_array(self.path / self.levels[level].name, mode="r")

    def dask_array(self, level: int = 0):
        """The level as a ``dask.array`` over its Zarr chunks (nothing is read until computed)."""
        import dask.array as da

        return da.from_zarr(self.zarr_array(level))

    def chunk_range(self):
        """Minimum and maximum of every level-0 chunk, shape ``(cz, cy, cx, 2)``, or None when not stored."""
        import zarr

        try:
            return np.asarray(zarr.open_array(self.path / "chunk_range", mode="r")[...])
        except Exception:  # absent (plain Zarr, other writers): the caller makes a first pass
            return None

    def region(self, level: int, slices) -> np.ndarray:
        """Samples ``[z, y, x]`` of a region of a level (slices in that level's samples)."""
        return np.asarray(self.zarr_array(level)[tuple(slices)])

    def volume(self, level: int = 0, *, budget: int = DEFAULT_BUDGET) -> Volume:
        """The level read into an in-memory :class:`Volume`, refused (one line) when it needs more than
        ``budget`` bytes."""
        size = self.nbytes(level)
        if size > budget:
            raise VolumeReadError(
                self.path, f"level {level} of this chunked volume needs {size / 2**30:.2f} GiB in memory, more than "
                f"the {budget / 2**30:.2f} GiB allowed",
                "Mesh it chunk by chunk ('voxelscope mesh --workers N'), or open a coarser level")
        lv = self.levels[level]
        metadata = {**self.metadata, "source_path": str(self.path), "level": level, "levels": len(self.levels)}
        return Volume(np.asarray(self.zarr_array(level)[...]), lv.spacing, lv.origin, self.direction,
                      self.modality, self.units, metadata)


# -- reading ----------------------------------------------------------------------------------------------------
def _group_attrs(path: Path) -> tuple[dict, int]:
    for marker, fmt in (("zarr.json", 3), (".zgroup", 2), (".zarray", 2)):
        if (path / marker).is_file():
            if marker == "zarr.json":
                meta = json.loads((path / marker).read_text())
                return meta.get("attributes", {}) or {}, 3
            attrs = path / ".zattrs"
            return (json.loads(attrs.read_text()) if attrs.is_file() else {}), fmt
    raise UnsupportedFormatError(path, "the folder holds no Zarr metadata (.zgroup, .zarray or zarr.json)",
                                 "Give the path of a Zarr or OME-Zarr store")


def _transforms(transformations, rank: int) -> tuple[np.ndarray, np.ndarray]:
    scale, translation = np.ones(rank), np.zeros(rank)
    for item in transformations or []:
        if item.get("type") == "scale":
            scale = scale * np.asarray(item["scale"], float)
        elif item.get("type") == "translation":
            translation = translation + np.asarray(item["translation"], float)
    return scale, translation


_UNITS_MM = {"millimeter": 1.0, "micrometer": 1e-3, "nanometer": 1e-6, "meter": 1e3, "centimeter": 10.0, None: 1.0}


def open_zarr(path) -> ChunkedVolume:
    """Open a Zarr v2/v3 array or an OME-Zarr group as a :class:`ChunkedVolume` (metadata only).

    Raises a :class:`VolumeReadError` subclass with a one-line message for anything that is not a 3D volume.
    """
    import zarr

    path = Path(path).expanduser()
    if not path.is_dir():
        raise VolumeReadError(path, "a Zarr store is a folder; this is not one", "Give the .zarr folder")
    try:
        attrs, fmt = _group_attrs(path)
    except (ValueError, OSError) as exc:
        raise CorruptFileError(path, f"the Zarr metadata cannot be read ({exc})", "The store may be damaged") from exc
    ome = attrs.get("ome", attrs)
    ours = attrs.get("voxelscope", {})
    warnings: list[str] = []
    try:
        if "multiscales" in ome:
            multiscale = ome["multiscales"][0]
            axes = multiscale.get("axes", [])
            names = [a["name"] if isinstance(a, dict) else a for a in axes]
            units = [a.get("unit") if isinstance(a, dict) else None for a in axes]
            space = [n for n, a in enumerate(axes) if not isinstance(a, dict) or a.get("type", "space") == "space"]
            if len(space) != 3:
                raise UnsupportedFormatError(path, f"the OME-Zarr has axes {names}; Voxelscope reads 3 space axes",
                                             "Select one channel and time point first (e.g. with ome-zarr tools)")
            if len(axes) != 3:
                raise UnsupportedFormatError(path, f"the OME-Zarr has axes {names} (channels or time)",
                                             "Voxelscope reads single-channel 3D volumes (axes z, y, x)")
            factor = np.array([_UNITS_MM.get(units[n], 1.0) for n in space])
            global_scale, global_translation = _transforms(multiscale.get("coordinateTransformations"), 3)
            levels = []
            for dataset in multiscale["datasets"]:
                array = zarr.open_array(path / dataset["path"], mode="r")
                if array.ndim != 3:
                    raise UnsupportedFormatError(path, f"level '{dataset['path']}' has {array.ndim} dimensions",
                                                 "Voxelscope reads 3D volumes")
                scale, translation = _transforms(dataset.get("coordinateTransformations"), 3)
                scale, translation = scale * global_scale * factor, (translation * global_scale
                                                                     + global_translation) * factor
                levels.append(Level(dataset["path"], tuple(int(s) for s in array.shape),
                                    tuple(int(c) for c in array.chunks), tuple(float(s) for s in scale[::-1]),
                                    tuple(float(t) for t in translation[::-1])))
            dtype = zarr.open_array(path / levels[0].name, mode="r").dtype
            source = f"OME-Zarr {ome.get('version', multiscale.get('version', ''))} (Zarr v{fmt})".replace("  ", " ")
        else:
            array = zarr.open_array(path, mode="r") if (path / ".zarray").is_file() or fmt == 3 and json.loads(
                (path / "zarr.json").read_text()).get("node_type") == "array" else None
            if array is None:
                raise UnsupportedFormatError(path, "the Zarr group has no OME multiscales metadata",
                                             "Give the path of the 3D array inside the group")
            if array.ndim != 3:
                raise UnsupportedFormatError(path, f"the Zarr array has {array.ndim} dimensions",
                                             "Voxelscope reads 3D volumes (z, y, x)")
            spacing = tuple(float(s) for s in ours.get("spacing", (1.0, 1.0, 1.0)))
            origin = tuple(float(o) for o in ours.get("origin", (0.0, 0.0, 0.0)))
            if "spacing" not in ours:
                warnings.append(f"{path.name}: plain Zarr array without geometry; 1 mm spacing assumed")
            levels = [Level("", tuple(int(s) for s in array.shape), tuple(int(c) for c in array.chunks), spacing,
                            origin)]
            dtype = array.dtype
            source = f"Zarr v{fmt}"
    except VolumeReadError:
        raise
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise CorruptFileError(path, f"the OME-Zarr metadata is incomplete ({type(exc).__name__}: {exc})",
                               "The store may be damaged or written by an unsupported tool") from exc
    dtype = np.dtype(dtype)
    if dtype.kind not in "iuf" and dtype != np.bool_:
        raise UnsupportedFormatError(path, f"unsupported sample type {dtype}", "Store integer or float samples")
    direction = np.asarray(ours.get("direction", np.eye(3).tolist()), float).reshape(3, 3)
    metadata = {"source_format": source, "source_path": str(path), "warnings": warnings,
                "value_range": ours.get("value_range"), "zarr_format": fmt}
    return ChunkedVolume(path, levels, dtype, direction, ours.get("modality", ""), ours.get("units", ""), metadata)


def read_zarr(path, *, level: int | None = None, budget: int | None = None) -> Volume:
    """Read a Zarr/OME-Zarr volume into memory: level 0 when it fits ``budget`` bytes, else the finest pyramid
    level that does, with a warning saying so (``level`` picks a level explicitly; a level that does not fit is
    refused in one line)."""
    chunked = open_zarr(path)
    budget = DEFAULT_BUDGET if budget is None else int(budget)
    if level is not None:
        return chunked.volume(level, budget=budget)
    chosen = chunked.coarsest_fitting(budget)
    volume = chunked.volume(chosen, budget=budget)
    if chosen > 0:
        lv = chunked.levels[chosen]
        volume.metadata.setdefault("warnings", []).append(
            f"{chunked.path.name}: opened pyramid level {chosen} ({'x'.join(map(str, lv.dimensions))} voxels, "
            f"{' x '.join(f'{s:g}' for s in lv.spacing)} mm): the full resolution needs "
            f"{chunked.nbytes(0) / 2**30:.1f} GiB; 'voxelscope mesh --workers N' meshes it chunk by chunk")
    return volume


# -- writing ----------------------------------------------------------------------------------------------------
def _compressor(name: str, zarr_format: int):
    if name not in COMPRESSORS:
        raise ValueError(f"compressor must be one of {', '.join(COMPRESSORS)}, got {name!r}")
    if name == "none":
        return None
    if zarr_format == 2:
        import numcodecs

        if name == "zstd":
            return numcodecs.Zstd(level=3)
        return numcodecs.Blosc(cname=name.split("-")[1], clevel=3, shuffle=numcodecs.Blosc.BITSHUFFLE)
    from zarr.codecs import BloscCodec, ZstdCodec

    if name == "zstd":
        return ZstdCodec(level=3)
    return BloscCodec(cname=name.split("-")[1], clevel=3, shuffle="bitshuffle")


def _pyramid_shapes(shape, min_size: int) -> list[tuple[int, int, int]]:
    shapes = [tuple(int(s) for s in shape)]
    while max(shapes[-1]) > min_size and min(shapes[-1]) >= 4:
        shapes.append(tuple(s // 2 for s in shapes[-1]))
    return shapes


def _create_levels(group, shapes, chunks: int, dtype, codec, zarr_format: int) -> list:
    arrays = []
    for n, shape in enumerate(shapes):
        block = tuple(min(chunks, s) for s in shape)
        kwargs = {"dimension_names": ("z", "y", "x")} if zarr_format == 3 else {}
        arrays.append(group.create_array(str(n), shape=shape, chunks=block, dtype=dtype, compressors=codec,
                                         fill_value=0, **kwargs))
    return arrays


def _halved(array):
    """Mean of 2x2x2 blocks (trailing odd samples dropped), in the array's type (rounded for integers)."""
    import dask.array as da

    nz, ny, nx = (s // 2 * 2 for s in array.shape)
    array = array[:nz, :ny, :nx]
    mean = da.coarsen(np.mean, array.astype(np.float64), {0: 2, 1: 2, 2: 2})
    return da.round(mean).astype(array.dtype) if array.dtype.kind in "iu" else mean.astype(array.dtype)


def _compute(tasks, progress, start: float, stop: float) -> list:
    """Compute dask collections on the local threads, reporting progress between ``start`` and ``stop``."""
    import dask
    from dask.callbacks import Callback

    class _Progress(Callback):
        def _start_state(self, dsk, state):
            self._total = max(len(dsk), 1)
            self._done = 0

        def _posttask(self, key, result, dsk, state, worker_id):
            self._done += 1
            if progress is not None:
                progress(start + (stop - start) * min(self._done / self._total, 1.0))

    with _Progress():
        return dask.compute(*tasks, scheduler="threads")


def _datasets(shapes, spacing, origin) -> list[dict]:
    datasets = []
    for n in range(len(shapes)):
        factor = 2.0 ** n
        datasets.append({"path": str(n), "coordinateTransformations": [
            {"type": "scale", "scale": (spacing * factor)[::-1].tolist()},
            {"type": "translation", "translation": (origin + (factor - 1) / 2 * spacing)[::-1].tolist()}]})
    return datasets


def _write_attributes(group, path, datasets, spacing, origin, direction, modality, units, chunk_range,
                      zarr_format) -> None:
    axes = [{"name": name, "type": "space", "unit": "millimeter"} for name in ("z", "y", "x")]
    multiscale = {"axes": axes, "datasets": datasets, "name": path.name.split(".")[0], "type": "mean"}
    ours = {"spacing": spacing.tolist(), "origin": origin.tolist(), "direction": direction.tolist(),
            "modality": modality, "units": units,
            "value_range": [float(chunk_range[..., 0].min()), float(chunk_range[..., 1].max())],
            "chunk_range": "chunk_range"}
    if zarr_format == 2:
        group.attrs.update({"multiscales": [{"version": "0.4", **multiscale}], "voxelscope": ours})
    else:
        group.attrs.update({"ome": {"version": "0.5", "multiscales": [multiscale]}, "voxelscope": ours})


def write_ome_zarr(array, path, *, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), direction=None,
                   chunks: int = 128, compressor: str = "blosc-zstd", levels: int | None = None,
                   zarr_format: int = 2, modality: str = "", units: str = "", overwrite: bool = False,
                   progress: Callable[[float], None] | None = None) -> Path:
    """Write a 3D array (NumPy or Dask, ``(nz, ny, nx)``) as an OME-Zarr pyramid, atomically.

    Parameters
    ----------
    spacing, origin : (x, y, z) mm
    direction : (3, 3), optional
        Columns: LPS directions of i, j, k (kept in the ``voxelscope`` attributes).
    chunks : int
        Chunk edge in samples (every level, clipped to its shape).
    compressor : {"blosc-zstd", "blosc-lz4", "zstd", "none"}
    levels : int, optional
        Number of levels (default: halve until the largest side is at most 128 samples).
    zarr_format : {2, 3}
        Zarr v2 with OME-NGFF 0.4 metadata, or Zarr v3 with OME-NGFF 0.5.

    The store is written under a temporary name beside ``path`` and renamed at the end; an existing ``path`` is
    refused unless ``overwrite``.
    """
    import dask.array as da
    import zarr

    path = Path(path).expanduser()
    if zarr_format not in (2, 3):
        raise ValueError(f"zarr_format must be 2 or 3, got {zarr_format!r}")
    chunks = int(chunks)
    if chunks < 8:
        raise ValueError(f"chunks must be at least 8 samples, got {chunks}")
    if path.exists() and not overwrite:
        raise FileExistsRefusal(path)
    codec = _compressor(compressor, zarr_format)
    source = array if hasattr(array, "dask") else da.from_array(np.asarray(array), chunks=chunks)
    if source.ndim != 3:
        raise ValueError(f"a volume needs a 3D array (nz, ny, nx), got shape {source.shape}")
    dtype = np.dtype(source.dtype)
    if dtype == np.bool_:
        source, dtype = source.astype(np.uint8), np.dtype(np.uint8)
    shapes = _pyramid_shapes(source.shape, 128)
    if levels is not None:
        if int(levels) < 1:
            raise ValueError(f"levels must be at least 1, got {levels}")
        shapes = shapes[: int(levels)] if int(levels) <= len(shapes) else _pyramid_shapes(source.shape, 1)[: int(levels)]
    spacing = np.asarray(spacing, float)
    origin = np.asarray(origin, float)
    direction = np.eye(3) if direction is None else np.asarray(direction, float).reshape(3, 3)
    with written_in_place(path) as temporary:
        group = zarr.open_group(temporary, mode="w", zarr_format=zarr_format)
        level_arrays = _create_levels(group, shapes, chunks, dtype, codec, zarr_format)
        datasets = _datasets(shapes, spacing, origin)
        # Level 0 and the range of each of its chunks in one pass over the source.
        level0 = source.rechunk(level_arrays[0].chunks)
        ranges = level0.map_blocks(lambda b: np.array([[[[b.min(), b.max()]]]], dtype=np.float64),
                                   dtype=np.float64, chunks=(1, 1, 1, 2), new_axis=3)
        share = 0.7 if len(shapes) > 1 else 1.0
        _, chunk_range = _compute([da.store(level0, level_arrays[0], lock=False, compute=False), ranges],
                                  progress, 0.0, share)
        group.create_array("chunk_range", data=np.asarray(chunk_range, dtype=np.float64), chunks=chunk_range.shape,
                           compressors=None)
        for n in range(1, len(shapes)):
            above = da.from_zarr(level_arrays[n - 1])
            halved = _halved(above)[tuple(slice(0, s) for s in shapes[n])].rechunk(level_arrays[n].chunks)
            # Rechunked to the stored chunks, so no two tasks write one chunk.
            _compute([da.store(halved, level_arrays[n], lock=False, compute=False)], progress,
                     share + (1 - share) * (n - 1) / (len(shapes) - 1),
                     share + (1 - share) * n / (len(shapes) - 1))
        _write_attributes(group, path, datasets, spacing, origin, direction, modality, units, chunk_range,
                          zarr_format)
    if progress is not None:
        progress(1.0)
    return path



@contextmanager
def written_in_place(path: Path):
    """A temporary store path beside ``path``, moved to ``path`` (replacing what was there) when the block ends
    without error; on any error it is removed and an ``OSError`` becomes a :class:`VolumeWriteError` naming ``path``.
    """
    temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        yield temporary
        if path.exists():
            shutil.rmtree(path) if path.is_dir() else path.unlink()
        os.replace(temporary, path)
    except BaseException as exc:
        shutil.rmtree(temporary, ignore_errors=True)
        if isinstance(exc, OSError):
            raise VolumeWriteError(f"{path}: could not write the OME-Zarr store ({exc}); check the free space "
                                   "and permissions") from exc
        raise


def save_zarr(volume: Volume, path, *, overwrite: bool = False, **options) -> Path:
    """Write an in-memory :class:`Volume` as OME-Zarr (options as :func:`write_ome_zarr`)."""
    return write_ome_zarr(volume.array, path, spacing=volume.spacing, origin=volume.origin,
                          direction=volume.direction, modality=volume.modality, units=volume.units,
                          overwrite=overwrite, **options)
