"""Mesh files written so that a failure is an error and never a file: binary STL, binary PLY and OBJ written by us,
VTP by VTK with its error code checked, each atomically and together with its JSON sidecar.

VTK's PLY and OBJ writers do not report a failed write (a full disk leaves a truncated file that looks complete to
the caller), so those formats, and binary STL, are written here with Python's file objects, which raise on every
failed write: the data goes to a temporary file next to the target (:mod:`app.io.atomic`), is flushed to disk, and
only then renamed over the target, together with the sidecar - both land or neither does. The bytes written are
checked against the size the format implies (STL and PLY: exactly; every format: not empty). Every error names
the user's file, never the temporary one; temporary files of killed runs are removed on the next write to the
folder.

Formats (what the readers of :mod:`app.io.meshes`, VTK, meshio, 3D Slicer and slicers for 3D printing read):

- STL: binary, 80-byte header, facet normals from the vertex winding (float32), attribute 0.
- PLY: ``binary_little_endian 1.0``, vertices ``x y z`` (and ``nx ny nz`` when the mesh has point normals) as
  float32, faces as ``list uchar int vertex_indices``.
- OBJ: text, ``v x y z`` with 9 significant digits (float32 round-trips exactly), ``vn`` when the mesh has point
  normals, faces ``f a b c`` (or ``f a//a b//b c//c``), 1-based.
- VTP: VTK XML polydata, zlib-compressed raw appended data, every array kept (strips too).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
from vtkmodules.util import numpy_support

from algorithms.common.progress import ProgressCallback, report
from algorithms.common.vtk_bridge import polydata_arrays

from .io.atomic import atomic_outputs, check_companions, sidecar_json, write_error
from .io.errors import VolumeWriteError
from .io.vtk_writing import write_with_vtk

MESH_SUFFIXES = (".stl", ".ply", ".obj", ".vtp")
#: Triangles (or points) formatted and written per block: bounds the memory of a write and paces its progress.
BLOCK = 1 << 18

_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (9,)), ("attribute", "<u2")])
_PLY_FACE = np.dtype([("count", "u1"), ("indices", "<i4", (3,))])


def sidecar_path(mesh_path) -> Path:
    """``skull.stl`` -> ``skull.stl.json``."""
    mesh_path = Path(mesh_path)
    return mesh_path.with_name(mesh_path.name + ".json")


def mesh_arrays(polydata) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Points ``(n, 3)`` float32, triangles ``(m, 3)`` int64 and point normals ``(n, 3)`` float32 (or None) of a
    triangle ``vtkPolyData`` (views on VTK's memory where the types allow)."""
    points, triangles = polydata_arrays(polydata)
    points = np.asarray(points, dtype=np.float32)
    normals = polydata.GetPointData().GetNormals()
    normals = None if normals is None else np.asarray(numpy_support.vtk_to_numpy(normals), dtype=np.float32)
    return points, np.asarray(triangles, dtype=np.int64).reshape(-1, 3), normals


def _blocks(count: int, progress: ProgressCallback, start: float, stop: float):
    for begin in range(0, count, BLOCK):
        yield begin, min(begin + BLOCK, count)
        report(progress, start + (stop - start) * min(begin + BLOCK, count) / max(count, 1))


def _write_stl(handle, points, triangles, normals, progress) -> int:
    header = b"Voxelscope binary STL"
    handle.write(header.ljust(80, b" "))
    handle.write(np.uint32(len(triangles)).tobytes())
    for begin, end in _blocks(len(triangles), progress, 0.0, 1.0):
        corners = points[triangles[begin:end]]  # (b, 3, 3) float32
        facet = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        length = np.linalg.norm(facet, axis=1, keepdims=True)
        np.divide(facet, length, out=facet, where=length > 0)
        record = np.zeros(end - begin, dtype=_STL_RECORD)
        record["normal"] = facet
        record["corners"] = corners.reshape(-1, 9)
        handle.write(record.tobytes())
    return 84 + 50 * len(triangles)


def _write_ply(handle, points, triangles, normals, progress) -> int:
    if len(points) and len(points) - 1 > np.iinfo(np.int32).max:
        raise ValueError("PLY stores vertex indices as 32-bit integers; this mesh has too many points")
    properties = ["property float x", "property float y", "property float z"]
    if normals is not None:
        properties += ["property float nx", "property float ny", "property float nz"]
    header = "\n".join(["ply", "format binary_little_endian 1.0", "comment Voxelscope mesh export",
                        f"element vertex {len(points)}", *properties, f"element face {len(triangles)}",
                        "property list uchar int vertex_indices", "end_header", ""]).encode("ascii")
    handle.write(header)
    columns = 6 if normals is not None else 3
    for begin, end in _blocks(len(points), progress, 0.0, 0.4):
        block = points[begin:end] if normals is None else np.hstack([points[begin:end], normals[begin:end]])
        handle.write(np.ascontiguousarray(block, dtype="<f4").tobytes())
    for begin, end in _blocks(len(triangles), progress, 0.4, 1.0):
        faces = np.empty(end - begin, dtype=_PLY_FACE)
        faces["count"] = 3
        faces["indices"] = triangles[begin:end]
        handle.write(faces.tobytes())
    return len(header) + 4 * columns * len(points) + _PLY_FACE.itemsize * len(triangles)


def _write_obj(handle, points, triangles, normals, progress) -> int | None:
    handle.write(b"# Voxelscope mesh export\n")
    for begin, end in _blocks(len(points), progress, 0.0, 0.35):
        np.savetxt(handle, points[begin:end], fmt="v %.9g %.9g %.9g")
    if normals is not None:
        for begin, end in _blocks(len(points), progress, 0.35, 0.6):
            np.savetxt(handle, normals[begin:end], fmt="vn %.9g %.9g %.9g")
    face = "f %d//%d %d//%d %d//%d" if normals is not None else "f %d %d %d"
    for begin, end in _blocks(len(triangles), progress, 0.6, 1.0):
        block = triangles[begin:end] + 1
        np.savetxt(handle, np.repeat(block, 2, axis=1) if normals is not None else block, fmt=face)
    return None  # text: no size to check beyond "not empty"


def _write_vtp(path: Path, polydata, progress) -> None:
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    write_with_vtk(vtkXMLPolyDataWriter, polydata, path)
    report(progress, 1.0)


_WRITERS: dict[str, Callable[..., int | None]] = {".stl": _write_stl, ".ply": _write_ply, ".obj": _write_obj}


def check_mesh_targets(path, *, sidecar: bool = True, overwrite: bool = False) -> Path:
    """Refuse an unknown format, an existing mesh or sidecar (unless ``overwrite``), a folder or a missing or
    read-only folder, before anything is computed or written. Returns ``path`` as a Path."""
    path = Path(path).expanduser()
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise VolumeWriteError(f"{path}: unknown mesh format '{suffix}'; use one of {', '.join(MESH_SUFFIXES)}")
    check_companions(path, [sidecar_path(path)] if sidecar else [], overwrite=overwrite)
    return path


def write_mesh_files(polydata, path, *, sidecar: dict[str, Any] | None = None, overwrite: bool = False,
                     progress: ProgressCallback = None) -> list[Path]:
    """Write a triangle surface (world coordinates, mm) by extension and, with ``sidecar``, ``<path>.json``;
    atomically and together. Returns the paths written.

    STL, PLY and OBJ take triangles (strips and polygons must be triangulated first); VTP keeps the polydata as it
    is. Errors are :class:`~app.io.errors.VolumeWriteError` naming ``path`` (or the sidecar, when that is what
    failed): a full disk, a missing folder, an existing file without ``overwrite``.
    """
    path = check_mesh_targets(path, sidecar=sidecar is not None, overwrite=overwrite)
    suffix = path.suffix.lower()
    targets = [path] + ([sidecar_path(path)] if sidecar is not None else [])
    text = sidecar_json(sidecar) if sidecar is not None else ""
    with atomic_outputs(targets, overwrite=overwrite) as temporaries:
        if suffix == ".vtp":
            _write_vtp(temporaries[0], polydata, progress)
        else:
            points, triangles, normals = mesh_arrays(polydata)
            with open(temporaries[0], "wb") as handle:
                expected = _WRITERS[suffix](handle, points, triangles, normals, progress)
            size = temporaries[0].stat().st_size
            if expected is not None and size != expected:
                raise VolumeWriteError(f"{path}: could not be written: {size} of {expected} bytes reached the disk")
        if sidecar is not None:
            try:
                temporaries[1].write_text(text)
            except OSError as exc:
                side = targets[1]
                raise VolumeWriteError(f"{write_error(side, exc)} (the sidecar of {path.name}; neither file was "
                                       "written)") from exc
    return targets
