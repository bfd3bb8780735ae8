"""The scene: the named items the workbench and the command line hold - volumes, scalar fields on a grid (masks,
distance fields), surface meshes, tetrahedral meshes - with the signals the window follows.

Every item knows where it lies in the patient (``bounds`` in LPS mm) and how to describe itself (``describe()``,
what ``voxelscope info`` prints). Gridded items keep their data in the volume frame and are placed by
``local_to_world``; meshes are stored in patient coordinates (LPS mm) as read or made.

Item kinds (``Item.kind``): ``"volume"`` (an image), ``"field"`` (a mask or a distance field on a grid; both are
gridded like volumes and every volume mode can show them), ``"mesh"``, ``"tetmesh"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Iterator

import numpy as np

from .events import Signal
from .io.meshes import Mesh, describe_mesh
from .volume import Volume

FIELD_ROLES = ("mask", "distance", "labels")


@dataclass(eq=False)
class Item:
    """Base of scene items. ``name`` is unique within a scene; ``metadata`` holds provenance and warnings."""

    kind: ClassVar[str] = "item"
    name: str
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """Axis-aligned LPS bounds ``(xmin, xmax, ymin, ymax, zmin, zmax)`` in mm."""
        raise TypeError(f"{type(self).__name__} has no extent")

    def describe(self) -> dict[str, Any]:
        return {"kind": self.kind, "name": self.name}


@dataclass(eq=False)
class VolumeItem(Item):
    """A volume (an image of the patient) in the scene."""

    kind: ClassVar[str] = "volume"
    volume: Volume = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if not isinstance(self.volume, Volume):
            raise TypeError(f"{self.name}: a volume item needs an app.volume.Volume")
        self._image = None

    @property
    def bounds(self):
        return self.volume.world_bounds

    @property
    def local_to_world(self) -> np.ndarray:
        return self.volume.local_to_world

    def vtk_image(self):
        """The volume as a ``vtkImageData`` in its volume frame, made once and shared by every view."""
        if self._image is None:
            self._image = self.volume.to_vtk(local=True)
        return self._image

    def describe(self) -> dict[str, Any]:
        return {"kind": self.kind, "name": self.name, **self.volume.describe()}


@dataclass(eq=False)
class FieldItem(VolumeItem):
    """A scalar field on a grid: a binary ``mask`` (inside = 1), a signed ``distance`` field in mm (negative
    inside), or integer ``labels``."""

    kind: ClassVar[str] = "field"
    role: str = "mask"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.role not in FIELD_ROLES:
            raise ValueError(f"{self.name}: a field's role is one of {', '.join(FIELD_ROLES)}, got {self.role!r}")

    @property
    def iso(self) -> float:
        """The level whose surface is the field's shape: 0 mm for distances, 0.5 for masks."""
        return 0.0 if self.role == "distance" else 0.5

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "role": self.role}


@dataclass(eq=False)
class MeshItem(Item):
    """A triangle surface in patient coordinates (LPS mm), as a ``vtkPolyData``."""

    kind: ClassVar[str] = "mesh"
    polydata: Any = None

    @property
    def bounds(self):
        return tuple(float(v) for v in self.polydata.GetBounds())

    @property
    def local_to_world(self) -> np.ndarray:
        return np.eye(4)

    @classmethod
    def from_mesh(cls, mesh, name: str | None = None) -> "MeshItem":
        """An item for a mesh read by :func:`app.io.meshes.load_mesh` (its provenance kept in the metadata)."""
        metadata = {"source_path": str(mesh.source_path), "source_format": mesh.source_format,
                    "warnings": list(mesh.warnings)}
        return cls(name or Path(mesh.source_path).name, polydata=mesh.polydata, metadata=metadata)

    def describe(self) -> dict[str, Any]:
        mesh = Mesh(self.polydata, Path(self.metadata.get("source_path", "")),
                    self.metadata.get("source_format", "mesh"), list(self.metadata.get("warnings", [])))
        return {"name": self.name, **describe_mesh(mesh)}


@dataclass(eq=False)
class TetMeshItem(Item):
    """A tetrahedral mesh in patient coordinates (LPS mm), as a ``vtkUnstructuredGrid`` of tetrahedra."""

    kind: ClassVar[str] = "tetmesh"
    grid: Any = None

    @property
    def bounds(self):
        return tuple(float(v) for v in self.grid.GetBounds())

    @property
    def local_to_world(self) -> np.ndarray:
        return np.eye(4)

    def describe(self) -> dict[str, Any]:
        return {"kind": self.kind, "name": self.name, "points": int(self.grid.GetNumberOfPoints()),
                "tetrahedra": int(self.grid.GetNumberOfCells()), "bounds": list(self.bounds)}


class Scene:
    """Named items in the order they were added; ``item_added``, ``item_removed`` and ``item_changed`` announce
    changes (each with the item)."""

    def __init__(self) -> None:
        self.item_added = Signal()
        self.item_removed = Signal()
        self.item_changed = Signal()
        self._items: dict[str, Item] = {}

    def __iter__(self) -> Iterator[Item]:
        return iter(list(self._items.values()))

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, name: str) -> bool:
        return name in self._items

    def names(self) -> list[str]:
        return list(self._items)

    def unique_name(self, wanted: str) -> str:
        """``wanted``, or ``wanted 2``, ``wanted 3``... if the name is taken."""
        wanted = wanted.strip() or "item"
        if wanted not in self._items:
            return wanted
        number = 2
        while f"{wanted} {number}" in self._items:
            number += 1
        return f"{wanted} {number}"

    def add(self, item: Item) -> Item:
        """Add ``item`` (renamed if its name is taken) and announce it."""
        item.name = self.unique_name(item.name)
        self._items[item.name] = item
        self.item_added.emit(item)
        return item

    def replace(self, name: str, item: Item) -> Item:
        """Put ``item`` in the place of the item called ``name`` (a new result of the same operation)."""
        if name not in self._items:
            raise KeyError(f"no item called {name!r} in the scene")
        item.name = name
        self._items[name] = item
        self.item_changed.emit(item)
        return item

    def remove(self, name: str) -> Item:
        item = self.get(name)
        del self._items[name]
        self.item_removed.emit(item)
        return item

    def clear(self) -> None:
        for name in list(self._items):
            self.remove(name)

    def get(self, name: str) -> Item:
        try:
            return self._items[name]
        except KeyError:
            choices = ", ".join(self._items) or "none"
            raise KeyError(f"no item called {name!r} in the scene (items: {choices})") from None

    def of_kind(self, *kinds: str) -> list[Item]:
        return [item for item in self._items.values() if item.kind in kinds]

    def first(self, *kinds: str) -> Item | None:
        items = self.of_kind(*kinds)
        return items[0] if items else None


def item_for(data, name: str, **extra) -> Item:
    """Wrap loaded data in the right item: a :class:`Volume` (``role=`` makes it a field), a ``vtkPolyData``
    or a ``vtkUnstructuredGrid``."""
    if isinstance(data, Volume):
        role = extra.pop("role", None)
        return FieldItem(name, volume=data, role=role, **extra) if role else VolumeItem(name, volume=data, **extra)
    if hasattr(data, "IsA") and data.IsA("vtkPolyData"):
        return MeshItem(name, polydata=data, **extra)
    if hasattr(data, "IsA") and data.IsA("vtkUnstructuredGrid"):
        return TetMeshItem(name, grid=data, **extra)
    raise TypeError(f"cannot put a {type(data).__name__} in the scene")
