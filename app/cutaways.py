"""Cut-away tools in the application: parsing ``--cut`` specifications, tool sets for a view's item, the cut volume
for surfaces and mesh export, the cropped volume of a ``keep`` box, and the state the views share.

The method is source 002's selection volume (Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern,
about 2009, sections 2.5 and 3.3.1); the tools are :class:`algorithms.fields.cutaway_tools.Tool` in LPS mm, evaluated per
sample by :mod:`algorithms.common.cutaway`.

Specifications (LPS mm, angles in degrees about x, then y, then z):

- ``sphere:X,Y,Z,R``
- ``box:X,Y,Z,SX,SY,SZ[,RX,RY,RZ]`` (centre, full sizes, rotation)
- ``cylinder:X,Y,Z,R,H[,RX,RY,RZ]`` (axis along z before the rotation)
- ``plane:X,Y,Z,NX,NY,NZ`` (the half-space the normal points into)
- ``mask:FILE[@TRANSFORM.json]`` (a binary mask, or a signed distance field in mm when its values are not just 0
  and 1, on its own grid; the JSON holds ``{"matrix": 4x4}`` or ``{"translation": [x, y, z],
  "rotation_degrees": [rx, ry, rz]}``, applied to the grid's LPS positions)
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from algorithms.fields.cutaway_tools import (Tool, box_tool, cut_volume, cylinder_tool, grid_tool, masked_copy, plane_tool,
                                         removed_mask, rotation_matrix, sphere_tool, tool_set)

from .events import Signal
from .io import load_volume
from .samples import resolve_path
from .volume import Volume

CUT_MODES = ("remove", "keep")
CUT_EVALUATIONS = ("binary", "distance")
_FORMS = {
    "sphere": "sphere:X,Y,Z,R",
    "box": "box:X,Y,Z,SX,SY,SZ[,RX,RY,RZ]",
    "cylinder": "cylinder:X,Y,Z,R,H[,RX,RY,RZ]",
    "plane": "plane:X,Y,Z,NX,NY,NZ",
    "mask": "mask:FILE[@TRANSFORM.json]",
}


def _numbers(kind: str, text: str, counts: tuple[int, ...]) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"--cut {kind}:{text}: the values must be numbers, as in {_FORMS[kind]} (LPS mm, "
                         "degrees)") from None
    if len(values) not in counts or not all(np.isfinite(values)):
        raise ValueError(f"--cut {kind}:{text}: expected {_FORMS[kind]} (LPS mm, degrees), got {len(values)} "
                         "values")
    return values


def parse_cut(spec: str, *, mode: str = "remove") -> Tool:
    """A :class:`Tool` from a ``--cut`` specification (see the module notes); a ValueError says what is wrong."""
    if mode not in CUT_MODES:
        raise ValueError(f"--cut-mode must be remove or keep, got {mode!r}")
    kind, _, rest = str(spec).partition(":")
    kind = kind.strip().lower()
    if kind not in _FORMS or not rest:
        raise ValueError(f"--cut {spec!r}: use one of " + "; ".join(_FORMS.values()))
    try:
        if kind == "sphere":
            x, y, z, r = _numbers(kind, rest, (4,))
            return sphere_tool((x, y, z), r, mode=mode)
        if kind == "box":
            v = _numbers(kind, rest, (6, 9))
            return box_tool(v[:3], v[3:6], v[6:9] if len(v) == 9 else (0, 0, 0), mode=mode)
        if kind == "cylinder":
            v = _numbers(kind, rest, (5, 8))
            return cylinder_tool(v[:3], v[3], v[4], v[5:8] if len(v) == 8 else (0, 0, 0), mode=mode)
        if kind == "plane":
            v = _numbers(kind, rest, (6,))
            return plane_tool(v[:3], v[3:6], mode=mode)
    except ValueError as exc:
        if str(exc).startswith("--cut"):
            raise
        raise ValueError(f"--cut {spec}: {exc}") from None
    return mask_tool_from_file(rest, mode=mode)


def _transform_from_json(path: Path) -> np.ndarray:
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"--cut mask: the transform file {path} does not exist") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"--cut mask: cannot read the transform {path} as JSON ({exc})") from None
    if isinstance(data, list):
        data = {"matrix": data}
    if not isinstance(data, dict):
        raise ValueError(f"--cut mask: {path} must hold {{\"matrix\": 4x4}} or translation/rotation_degrees")
    if "matrix" in data:
        matrix = np.asarray(data["matrix"], dtype=np.float64)
        if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)) or abs(np.linalg.det(matrix)) < 1e-12:
            raise ValueError(f"--cut mask: the matrix in {path} must be a finite, invertible 4x4 matrix")
        return matrix

    matrix = np.eye(4)
    try:
        matrix[:3, :3] = rotation_matrix(data.get("rotation_degrees", (0, 0, 0)))
        matrix[:3, 3] = np.asarray(data.get("translation", (0, 0, 0)), dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"--cut mask: translation and rotation_degrees in {path} must be three numbers each") from None
    return matrix


def mask_tool_from_file(text: str, *, mode: str = "remove") -> Tool:
    """A grid tool from ``FILE[@TRANSFORM.json]``: a mask (values 0 and 1 only) or a distance field (mm)."""
    file_text, _, transform_text = text.partition("@")
    path = resolve_path(file_text)
    if not Path(path).exists():
        raise ValueError(f"--cut mask: {path} does not exist; give a mask or distance-field volume file")
    transform = _transform_from_json(Path(transform_text).expanduser()) if transform_text else None
    volume = load_volume(path)
    values = volume.array
    unique = np.unique(values[:: max(1, values.size // 1_000_000)])
    role = "mask" if np.all(np.isin(unique, (0, 1))) else "distance"
    tool = grid_tool(values, volume.grid, role=role, transform=transform, mode=mode, label=Path(path).name)
    return replace(tool, source=str(Path(path).resolve()))


def tools_from_specs(specs, *, mode: str = "remove") -> list[Tool]:
    return [parse_cut(spec, mode=mode) for spec in specs or ()]


# -- tools for a volume ------------------------------------------------------------------------------------------------
def tool_set_for(volume: Volume, tools, *, evaluation: str = "binary", moving: bool = False,
                 frame_to_world=None):
    """The visible ``tools`` as a :class:`~algorithms.common.cutaway.ToolSet` in ``volume``'s frame (index times
    spacing, mm), with the transition width of one (smallest) voxel; ``moving`` takes the cheap path (no tool normals
    at the cut). None when no tool is visible."""
    visible = [tool for tool in tools if tool.visible]
    if not visible:
        return None
    frame = volume.local_to_world if frame_to_world is None else frame_to_world
    width = float(min(volume.spacing))
    return tool_set(visible, frame, evaluation=evaluation, width=width, cut_normals=not moving)


def cut_for_surface(volume: Volume, tools, iso: float, *, evaluation: str = "binary", progress=None) -> Volume:
    """``volume`` with the tools' CSG difference written in (see :func:`algorithms.fields.cutaway_tools.cut_volume`), so
    its ``iso`` surface is the surface of what is left, capped at the cut. ``volume`` itself without tools."""
    tools_in_frame = tool_set_for(volume, tools, evaluation=evaluation)
    if tools_in_frame is None:
        return volume
    array = cut_volume(volume.array, tools_in_frame, volume.spacing, float(iso), progress=progress)
    return volume.with_array(array)


def masked_volume(volume: Volume, tools, *, background: float | None = None) -> Volume:
    """``volume`` with the voxels the tools remove set to ``background`` (default: its minimum): the "pre-masked"
    volume (what our renderers never build; VTK's CPU mapper needs it, and the tests compare against it)."""
    tools_in_frame = tool_set_for(volume, tools)
    if tools_in_frame is None:
        return volume
    return volume.with_array(masked_copy(volume.array, tools_in_frame, volume.spacing, background))


def cropped_volume(volume: Volume, tools, *, background: float | None = None) -> Volume:
    """The region the ``keep`` tools leave, on the volume's own grid (cropped to the voxels inside their bounds;
    voxels outside the tools set to ``background``, default the minimum). A ValueError when no visible tool is in
    ``keep`` mode or the tools leave nothing of the volume."""
    keep = [tool for tool in tools if tool.visible and tool.mode == "keep"]
    if not keep:
        raise ValueError("export of a cropped volume needs a tool in keep mode (a box, for a region of interest)")
    masked = masked_volume(volume, tools, background=background)
    removed = tool_set_for(volume, tools)

    kept = ~removed_mask(removed, volume.array.shape, volume.spacing)
    if not kept.any():
        raise ValueError("the keep tools leave no voxel of the volume; move them over the volume first")
    ranges = []
    for axis in (2, 1, 0):  # i, j, k
        other = tuple(a for a in range(3) if a != axis)
        present = np.flatnonzero(kept.any(axis=other))
        ranges.append((int(present[0]), int(present[-1]) + 1))
    return masked.crop(*ranges)


def removed_overlay(volume: Volume, tools, *, progress=None) -> Volume | None:
    """A mask (uint8, 1 where the tools remove) on ``volume``'s grid, for shading the removed region over the slice
    views; None without visible tools. (``progress`` is accepted for workers; the evaluation is one pass.)"""
    tools_in_frame = tool_set_for(volume, tools)
    if tools_in_frame is None:
        return None
    return volume.with_array(removed_mask(tools_in_frame, volume.array.shape, volume.spacing).astype(np.uint8))


def describe_tools(tools, evaluation: str, seconds: float | None = None) -> dict:
    """JSON-ready report of the tools used (and the seconds the cut added)."""
    out = {"tools": [tool.describe() for tool in tools], "evaluation": evaluation}
    if seconds is not None:
        out["seconds"] = seconds
    return out


def default_tool(shape: str, world_bounds, *, mode: str = "remove") -> Tool:
    """A new tool of ``shape`` (box, sphere, cylinder or plane) for a volume with LPS ``world_bounds``: a box is the
    right anterior superior octant (the classic cut-away, which clipping planes cannot make), a sphere and a cylinder
    sit at the centre of that octant, a plane through the centre removes the anterior half (normal -y)."""
    b = np.asarray(world_bounds, dtype=np.float64)
    low, high = b[0::2], b[1::2]
    centre, extent = (low + high) / 2, np.maximum(high - low, 1e-3)
    octant = centre + extent * np.array([-0.25, -0.25, 0.25])  # right (-x), anterior (-y), superior (+z) in LPS
    if shape == "box":
        return box_tool(octant, extent / 2, mode=mode)
    if shape == "sphere":
        return sphere_tool(octant, float(extent.min()) / 4, mode=mode)
    if shape == "cylinder":
        return cylinder_tool(octant, float(extent[:2].min()) / 6, float(extent[2]) / 2, mode=mode)
    if shape == "plane":
        return plane_tool(centre, (0.0, -1.0, 0.0), mode=mode)
    raise ValueError(f"a new tool is a box, sphere, cylinder or plane, not {shape!r}")


# -- tools as data (sessions) ------------------------------------------------------------------------------------------
def tool_to_dict(tool: Tool) -> dict:
    """A tool as JSON-ready data: its shape, frame (4x4, to LPS mm), sizes (mm), mode, visibility and label; a grid
    tool by the file its values came from (:attr:`Tool.source`), which :func:`tool_from_dict` reads again. A grid
    tool made in memory has no such file: a ValueError says so."""
    data = {"shape": tool.shape, "matrix": np.asarray(tool.matrix).tolist(), "size": list(tool.size),
            "mode": tool.mode, "visible": bool(tool.visible), "label": tool.label}
    if tool.shape == "grid":
        if not tool.source:
            raise ValueError(f"the cut-away tool {tool.label or 'grid'} was made in memory and has no file to be "
                             "read from again")
        data.update(source=tool.source, role=tool.role)
    return data


def tool_from_dict(data: dict) -> Tool:
    """The tool :func:`tool_to_dict` wrote (a ValueError naming what is wrong or missing)."""
    try:
        shape, matrix = str(data["shape"]), np.asarray(data["matrix"], dtype=np.float64)
        extra = {"mode": str(data.get("mode", "remove")), "visible": bool(data.get("visible", True)),
                 "label": str(data.get("label", ""))}
        if shape != "grid":
            return Tool(shape, matrix, tuple(float(v) for v in data.get("size", ())), **extra)
        source = str(data["source"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"a cut-away tool in the session is incomplete or invalid ({exc})") from None
    tool = mask_tool_from_file(source, mode=extra["mode"])
    if data.get("role", tool.role) != tool.role:
        raise ValueError(f"the cut-away tool's file {source} no longer holds a {data['role']} (it holds a {tool.role})")
    return replace(tool, matrix=matrix, visible=extra["visible"], label=extra["label"] or tool.label)


# -- the state the views share ------------------------------------------------------------------------------------------
@dataclass
class Cutaways:
    """The cut-away tools of a workbench and how they are evaluated. ``changed(moving)`` is emitted on every change
    (``moving`` while a widget is being dragged: views take the cheap path, and refine when it is False again)."""

    tools: list[Tool] = field(default_factory=list)
    evaluation: str = "binary"
    changed: Signal = field(default_factory=Signal)

    def set_tools(self, tools, *, moving: bool = False) -> None:
        self.tools = list(tools)
        self.changed.emit(moving)

    def replace(self, index: int, tool: Tool, *, moving: bool = False) -> None:
        self.tools[index] = tool
        self.changed.emit(moving)

    def add(self, tool: Tool) -> int:
        """Append ``tool``; returns its index."""
        self.tools.append(tool)
        self.changed.emit(False)
        return len(self.tools) - 1

    def remove(self, index: int) -> None:
        del self.tools[index]
        self.changed.emit(False)

    def set_evaluation(self, evaluation: str) -> None:
        if evaluation not in CUT_EVALUATIONS:
            raise ValueError(f"the cut evaluation is binary or distance, got {evaluation!r}")
        self.evaluation = evaluation
        self.changed.emit(False)

    def to_dict(self) -> dict:
        """The tools and their evaluation as JSON-ready data (see :func:`tool_to_dict`)."""
        return {"evaluation": self.evaluation, "tools": [tool_to_dict(tool) for tool in self.tools]}

    def restore(self, data: dict) -> None:
        """Replace the tools and evaluation by what :meth:`to_dict` wrote (checked before anything changes)."""
        evaluation = data.get("evaluation", "binary")
        if evaluation not in CUT_EVALUATIONS:
            raise ValueError(f"the session's cut evaluation is binary or distance, got {evaluation!r}")
        tools = [tool_from_dict(entry) for entry in data.get("tools", [])]
        self.evaluation = evaluation
        self.set_tools(tools)


class Stopwatch:
    """Adds up the seconds spent on cut work (the JSON reports' ``cut.seconds``)."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def __enter__(self):
        self._start = time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        self.seconds += time.perf_counter() - self._start
