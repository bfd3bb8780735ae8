"""Writing tetrahedral meshes through meshio: VTU, Gmsh ``.msh``, MEDIT ``.mesh`` and Abaqus ``.inp``, atomically,
never over an existing file unless asked, with a JSON sidecar (``<file>.json``: source, isovalue, lattice spacing,
alphas, the quality report, counts, timings).

meshio (a well-kept library for mesh formats) writes every format; VTU files carry the cell array
``min_dihedral_deg``. Points are in patient coordinates (LPS mm), tetrahedra in VTK's order (positive volume).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .atomic import atomic_outputs, sidecar_json
from .errors import FileExistsRefusal, VolumeWriteError

#: File extension -> meshio format.
TET_FORMATS = {".vtu": "vtu", ".msh": "gmsh", ".mesh": "medit", ".inp": "abaqus"}


def sidecar_path(path) -> Path:
    path = Path(path)
    return path.with_name(path.name + ".json")


def tetmesh_format(path) -> str:
    """The meshio format of an output path (a VolumeWriteError names the choices otherwise)."""
    suffix = Path(path).suffix.lower()
    if suffix not in TET_FORMATS:
        raise VolumeWriteError(f"{path}: unknown tetrahedral mesh format '{suffix or 'none'}'; use one of "
                               f"{', '.join(TET_FORMATS)}")
    return TET_FORMATS[suffix]


def check_targets(path, *, overwrite: bool, sidecar: bool = True) -> list[Path]:
    """The files an export will write, refused up front if one exists (unless ``overwrite``) or the format is
    unknown."""
    path = Path(path).expanduser()
    tetmesh_format(path)
    targets = [path, sidecar_path(path)] if sidecar else [path]
    if not overwrite:
        for target in targets:
            if target.exists():
                raise FileExistsRefusal(target)
    return targets


def write_tetmesh(mesh, path, *, overwrite: bool = False, sidecar: dict[str, Any] | None = None,
                  min_angles: np.ndarray | None = None) -> list[Path]:
    """Write a :class:`~algorithms.common.mesh.TetMesh` (and its sidecar) by the path's extension; returns the
    paths written. Nothing is replaced unless ``overwrite``; a failure leaves no partial file."""
    import meshio

    path = Path(path).expanduser()
    file_format = tetmesh_format(path)
    targets = check_targets(path, overwrite=overwrite, sidecar=sidecar is not None)
    cell_data = {}
    if min_angles is not None and file_format == "vtu":
        cell_data["min_dihedral_deg"] = [np.asarray(min_angles, dtype=np.float64)]
    data = meshio.Mesh(np.asarray(mesh.points, dtype=np.float64),
                       [("tetra", np.asarray(mesh.tetrahedra, dtype=np.int64))], cell_data=cell_data)
    with atomic_outputs(targets, overwrite=overwrite) as temporaries:
        try:
            meshio.write(str(temporaries[0]), data, file_format=file_format)
        except Exception as exc:  # meshio raises many kinds; name the user's file
            raise VolumeWriteError(f"{path}: meshio could not write {file_format}: {exc}") from exc
        if sidecar is not None:
            temporaries[1].write_text(sidecar_json(sidecar))
    return targets


def tetmesh_provenance(volume, result, *, output: Path) -> dict[str, Any]:
    """The sidecar: software, source, isovalue, method and its parameters (h, alphas), coordinates, the quality
    report, counts and timings."""
    return {
        "software": f"Voxelscope {__version__}",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "output": str(output),
        "source_file": volume.metadata.get("source_path", ""),
        "source_format": volume.metadata.get("source_format", ""),
        "modality": volume.modality,
        "value_units": volume.units_label,
        **result.parameters,
        "coordinate_system": "LPS",
        "length_units": "mm",
        "counts": {"tetrahedra": result.mesh.n_tetrahedra, "points": result.mesh.n_points},
        "seconds": result.seconds,
        "stats": result.stats,
        "quality": result.quality,
    }
