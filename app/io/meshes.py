"""Surface meshes as input: :func:`load_mesh` and :func:`describe_mesh`.

Formats: STL (binary and ASCII), Wavefront OBJ, PLY (ASCII and binary), VTK XML polydata (VTP), OFF, and each of
them gzipped (``.stl.gz``, ``.obj.gz``, ...). A gzipped file is inflated in chunks with a size cap into a private
temporary folder (prefix ``.voxelscope-tmp-``, removed afterwards) and read from there; a CRC error or a truncated
stream is an error.

Every file is checked before VTK reads it (:mod:`app.io.mesh_formats`), and VTK's output is checked again: finite
coordinates, every cell index inside the points. The result holds triangles only: polygons and strips are
triangulated (``vtkTriangleFilter``), exactly coincident points are merged (an exact merge, like
``vtkCleanPolyData`` with tolerance 0), triangles that collapse (two corners the same point) are dropped and
counted in the warnings, and lines and vertices are dropped (counted too). Every failure is a
:class:`MeshReadError` with a one-line message naming the file.

Coordinates are taken as millimetres in the file's own frame (mesh formats carry no units or patient frame).

``orientation`` in :func:`describe_mesh`
    "outward" or "inward" when every closed piece faces away from (or into) the solid it bounds, judged by the
    sign of its enclosed volume and its nesting depth (:func:`algorithms.compare.topology.orientation_outward`);
    "mixed" when the winding flips across an edge or closed pieces disagree; "undefined" when the mesh has no
    closed piece (an open surface, such as the scanned bunny with holes in its base, has no inside, so
    facing out or in is not defined) or its closed pieces enclose no volume. Open pieces next to closed ones do
    not change the verdict of the closed ones.
"""

from __future__ import annotations

import importlib
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPolyData

from algorithms.common.vtk_bridge import (cell_array_from_offsets, vtk_points, VTKError, run_algorithm, cell_arrays,
                                          polydata_from_arrays, polydata_arrays)

from .atomic import TEMP_PREFIX
from .errors import MeshReadError, VolumeReadError
from .mesh_formats import check_obj, check_ply, check_stl, read_off, sniff
from .safety import inflate_prefix, memory_available, one_line, require_regular_file
from .vtkimage import check_vtk_xml

#: Mesh formats by (lower-case) extension.
MESH_FORMATS = {".stl": "STL", ".obj": "OBJ", ".ply": "PLY", ".vtp": "VTP", ".off": "OFF"}
#: Every mesh suffix :func:`load_mesh` reads, plain and gzipped.
MESH_SUFFIXES_READ = tuple(MESH_FORMATS) + tuple(f"{s}.gz" for s in MESH_FORMATS)


@dataclass
class Mesh:
    """A triangle mesh read from a file: ``polydata`` (triangles only) and where it came from.

    ``points`` is ``(n, 3)`` float64 (x, y, z) and ``triangles`` ``(m, 3)`` int64 vertex indices, views of the
    polydata's arrays.
    """

    polydata: Any
    source_path: Path
    source_format: str
    warnings: list[str] = field(default_factory=list)

    @property
    def points(self) -> np.ndarray:
        return np.asarray(polydata_arrays(self.polydata)[0], dtype=np.float64)

    @property
    def triangles(self) -> np.ndarray:
        return polydata_arrays(self.polydata)[1]


def mesh_suffix(path) -> str | None:
    """``.stl``, ``.obj``, ... for a mesh path (``.gz`` removed), or None."""
    name = Path(path).name.lower()
    if name.endswith(".gz"):
        name = name[:-3]
    suffix = Path(name).suffix
    return suffix if suffix in MESH_FORMATS else None


def is_mesh_path(path) -> bool:
    """True if ``path`` names a mesh format by its extension (so callers can dispatch volume vs mesh)."""
    return mesh_suffix(path) is not None


def load_mesh(path) -> Mesh:
    """Read a surface mesh (see the module notes); raises :class:`MeshReadError` naming the file."""
    path = Path(path).expanduser()
    try:
        return _load(path)
    except MeshReadError:
        raise
    except VolumeReadError as exc:  # the shared safety checks (special files, memory)
        raise MeshReadError(exc.path or path, exc.problem, exc.hint) from exc
    except MemoryError as exc:
        raise MeshReadError(path, "there is not enough memory to read it") from exc
    except Exception as exc:  # the last line of defence: an exception no check anticipated
        error = MeshReadError(path, f"the mesh could not be read ({type(exc).__name__}: {one_line(exc)[:200]})",
                              "It may be damaged or in an unsupported variant of its format")
        error.unexpected = True
        raise error from exc


def _load(path: Path) -> Mesh:
    suffix = mesh_suffix(path)
    if suffix is None:
        raise MeshReadError(path, f"'{path.suffix or path.name}' is not a mesh format",
                            f"Voxelscope reads meshes as {', '.join(MESH_SUFFIXES_READ)}")
    if not path.exists():
        raise MeshReadError(path, "no such file", "Check the path")
    size = require_regular_file(path).st_size
    if size == 0:
        raise MeshReadError(path, "the file is empty (0 bytes)", "Re-export or re-copy it")
    if not path.name.lower().endswith(".gz"):
        return _read_plain(path, suffix, path, "")
    folder = Path(tempfile.mkdtemp(prefix=TEMP_PREFIX))
    try:
        inner = folder / Path(path.name[:-3]).name
        limit = max(min(memory_available() // 4, 16 << 30), 1 << 20)
        with open(path, "rb") as source:
            data, _ = inflate_prefix(source, "gzip", path, limit=limit, keep=limit, what="the gzip stream")
        try:
            inner.write_bytes(data)
        except OSError as exc:
            raise MeshReadError(path, f"it could not be unpacked into a temporary folder ({exc.strerror})",
                                "Free some space in the temporary folder") from exc
        del data
        if inner.stat().st_size == 0:
            raise MeshReadError(path, "the gzip stream holds an empty file")
        return _read_plain(inner, suffix, path, " (gzip)")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _read_plain(file: Path, suffix: str, shown: Path, compression: str) -> Mesh:
    fmt = MESH_FORMATS[suffix]
    looks = sniff(file)
    if looks is not None and looks != fmt:
        raise MeshReadError(shown, f"the file holds {looks} data, not {fmt}", f"Rename it with the {looks} extension")
    warn: list[str] = []
    if fmt == "STL":
        variant = check_stl(file, shown)
        polydata = _vtk_read("vtkIOGeometry", "vtkSTLReader", file, shown)
        label = f"STL ({variant})"
    elif fmt == "OBJ":
        with open(file, "rb") as handle:
            if looks is None and b"\0" in handle.read(4096):
                raise MeshReadError(shown, "the file holds binary data, not OBJ text")
        check_obj(file, shown)
        polydata = _vtk_read("vtkIOGeometry", "vtkOBJReader", file, shown)
        label = "OBJ"
    elif fmt == "PLY":
        check_ply(file, shown)
        polydata = _vtk_read("vtkIOPLY", "vtkPLYReader", file, shown)
        label = "PLY"
    elif fmt == "VTP":
        try:
            check_vtk_xml(file, "PolyData")
        except VolumeReadError as exc:
            raise MeshReadError(shown, exc.problem, exc.hint) from exc
        polydata = _vtk_read("vtkIOXML", "vtkXMLPolyDataReader", file, shown)
        label = "VTP"
    else:
        points, offsets, connectivity = read_off(file, shown)
        polydata = vtkPolyData()
        polydata.SetPoints(vtk_points(points))
        polydata.SetPolys(cell_array_from_offsets(offsets, connectivity))
        label = "OFF"
    return _finish(polydata, shown, label + compression, warn)


def _vtk_read(module: str, name: str, file: Path, shown: Path):
    reader = getattr(importlib.import_module(f"vtkmodules.{module}"), name)()
    reader.SetFileName(str(file))
    try:
        output = run_algorithm(reader)
    except VTKError as exc:
        raise MeshReadError(shown, f"VTK could not read the file ({one_line(exc)[:200]})",
                            "It may be damaged or truncated") from exc
    if output is None or output.GetClassName() != "vtkPolyData":
        raise MeshReadError(shown, "the reader produced no surface")
    return output


def _cells(cell_array) -> tuple[np.ndarray, np.ndarray]:
    if cell_array is None or cell_array.GetNumberOfCells() == 0:
        return np.zeros(1, dtype=np.int64), np.empty(0, dtype=np.int64)
    offsets, connectivity = cell_arrays(cell_array)
    return np.asarray(offsets, dtype=np.int64), np.asarray(connectivity, dtype=np.int64)


def _finish(polydata, shown: Path, label: str, warn: list[str]) -> Mesh:
    """Validate VTK's output and reduce it to merged points and proper triangles."""
    count = polydata.GetNumberOfPoints()
    if count == 0 or polydata.GetPoints() is None:
        raise MeshReadError(shown, "the file holds no points")
    points = np.asarray(numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()), dtype=np.float64)
    if not np.all(np.isfinite(points)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(points), axis=1)))
        raise MeshReadError(shown, f"{bad} of {count} points have NaN or infinite coordinates", "The file is damaged")
    dropped = {}
    for kind in ("Verts", "Lines", "Polys", "Strips"):
        offsets, connectivity = _cells(getattr(polydata, f"Get{kind}")())
        if connectivity.size and (connectivity.min() < 0 or connectivity.max() >= count):
            raise MeshReadError(shown, f"a face names point {int(connectivity.max())} but there are only {count} "
                                       "points (index out of range)", "The file is damaged")
        if kind in ("Verts", "Lines"):
            dropped[kind] = len(offsets) - 1
    offsets, connectivity = _cells(polydata.GetPolys())
    strips = polydata.GetNumberOfStrips()
    if len(offsets) - 1 == 0 and strips == 0:
        raise MeshReadError(shown, "the file holds no faces (no triangles or polygons)")
    if strips or not np.all(np.diff(offsets) == 3):
        if np.any(np.diff(offsets) < 3):
            raise MeshReadError(shown, "a polygon has fewer than 3 corners")
        polydata = _triangulate(polydata, shown)
        offsets, connectivity = _cells(polydata.GetPolys())
        points = np.asarray(numpy_support.vtk_to_numpy(polydata.GetPoints().GetData()), dtype=np.float64)
    triangles = connectivity.reshape(-1, 3)
    for kind, number in dropped.items():
        if number:
            warn.append(f"{shown.name}: {number} {'line' if kind == 'Lines' else 'vertex'} cell(s) dropped (only "
                        "faces are kept)")
    points, triangles, degenerate = _merged(points, triangles)
    if degenerate:
        warn.append(f"{shown.name}: {degenerate} degenerate triangle(s) dropped (two corners at the same point)")
    if len(triangles) == 0:
        raise MeshReadError(shown, "every face of the file is degenerate; no triangle remains")
    corners = points[triangles]
    flat = int(np.count_nonzero(np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                                               axis=1) == 0))
    if flat:
        warn.append(f"{shown.name}: {flat} triangle(s) have zero area (collinear corners); kept")
    return Mesh(polydata_from_arrays(points, triangles), shown, label, warn)


def _triangulate(polydata, shown: Path):
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter

    triangles = vtkTriangleFilter()
    triangles.SetInputData(polydata)
    triangles.PassVertsOff()
    triangles.PassLinesOff()
    try:
        return run_algorithm(triangles)
    except VTKError as exc:
        raise MeshReadError(shown, f"the polygons could not be triangulated ({one_line(exc)[:200]})") from exc


def _merged(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Merge exactly coincident points, drop collapsed triangles and unused points."""
    unique, first, inverse = np.unique(points + 0.0, axis=0, return_index=True, return_inverse=True)  # -0.0 == 0.0
    order = np.argsort(first)  # keep the file's point order (first occurrence) rather than sorted coordinates
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    unique = unique[order]
    triangles = rank[inverse.reshape(-1)][triangles]
    collapsed = (triangles[:, 0] == triangles[:, 1]) | (triangles[:, 1] == triangles[:, 2]) | \
                (triangles[:, 0] == triangles[:, 2])
    triangles = triangles[~collapsed]
    used = np.zeros(len(unique), dtype=bool)
    used[triangles.ravel()] = True
    remap = np.cumsum(used) - 1
    return unique[used], remap[triangles], int(np.count_nonzero(collapsed))


def describe_mesh(mesh: Mesh) -> dict[str, Any]:
    """What ``voxelscope info MESH --json`` prints (see the module notes for ``orientation``)."""
    from algorithms.compare.measures import enclosed_volume, surface_area
    from algorithms.compare.topology import connected_components, edge_manifoldness, orientation_outward

    points, triangles = mesh.points, mesh.triangles
    edges = edge_manifoldness(points, triangles)
    report = orientation_outward(points, triangles)
    orientation = _orientation(edges, report)
    watertight = edges.boundary_edges == 0 and edges.odd_edges == 0
    volume = None
    if watertight and orientation in ("outward", "inward"):
        volume = abs(float(enclosed_volume(points, triangles)))
    low, high = points.min(axis=0), points.max(axis=0)
    return {
        "kind": "mesh",
        "source_path": str(mesh.source_path),
        "source_format": mesh.source_format,
        "points": int(len(points)),
        "triangles": int(len(triangles)),
        "closed": bool(edges.boundary_edges == 0),
        "boundary_edges": int(edges.boundary_edges),
        "non_manifold_edges": int(edges.nonmanifold_edges),
        "non_manifold_vertices": int(edges.nonmanifold_vertices),
        "components": int(connected_components(points, triangles)),
        "bounds": [float(v) for pair in zip(low, high) for v in pair],
        "orientation": orientation,
        "area_mm2": float(surface_area(points, triangles)),
        "volume_mm3": volume,
        "warnings": list(mesh.warnings),
    }


def _orientation(edges, report) -> str:
    if edges.inconsistent_edges:
        return "mixed"
    closed = np.asarray(report.closed, dtype=bool)
    if not closed.any():
        return "undefined"
    expected = np.where(np.asarray(report.depth)[closed] % 2 == 0, 1.0, -1.0)
    signs = np.sign(np.asarray(report.volumes)[closed]) * expected
    if np.all(signs > 0):
        return "outward"
    if np.all(signs < 0):
        return "inward"
    if np.all(signs == 0):
        return "undefined"
    return "mixed"
