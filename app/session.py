"""Workbench sessions: one JSON file with the data paths, the item on show, the layout, each view's mode and
options, the camera, the isovalue, the transfer function, window/level, the slice cursor and its oblique rotation,
the measurements, the cut-away tools, and the window's own layout (dock arrangement, window geometry, which view is
enlarged), so that a session saved today opens tomorrow as it was. ``voxelscope gui --session FILE`` and File > Open
session read it; version 1 files (before cut-away tools and made items were stored) still open.

Data are stored by reference (their files' absolute paths): the volume, its label maps, the meshes opened. What was
made in the session - masks, distance fields, surfaces, tetrahedral meshes - has no file of its own, so
:func:`save_session` writes each into a folder beside the session file (``NAME.items/``, NRRD for fields, VTP for
surfaces, VTU for tetrahedral meshes, in patient coordinates) and :func:`load_items` reads them back.

The model part is Qt-free (:func:`model_state`, :func:`apply_model_state`); the window adds its own keys under
``"ui"`` (opaque to this module). Files are written atomically and never replaced without being asked.
"""

from __future__ import annotations

import copy
import json
import uuid
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.camera import Camera

from .io import save_volume, load_volume
from .io.atomic import atomic_output, check_target, numpy_json
from .io.meshes import load_mesh
from .io.vtk_writing import write_with_vtk
from .measurements import Measurement
from .mesh_files import write_mesh_files
from .scene import FieldItem, MeshItem, TetMeshItem
from .transfer import Shading, TransferFunction

FORMAT = "voxelscope-session"
VERSION = 2  # 2: cut-away tools and their evaluation, and the items made in the session

#: Where each piece of :class:`app.workbench.WorkbenchModel` state goes in a session (the model's attribute -> the
#: session's key). A test compares this with the model's attributes, so a new piece of state cannot be forgotten.
MODEL_FIELDS = {
    "scene": "data", "base": "data", "item": "shown_item",
    "iso": "iso", "preset": "preset", "transfer_function": "transfer_function",
    "window": "window_level", "level": "window_level",
    "layout": "layout", "view_modes": "view_modes", "view_options": "view_options",
    "cameras_linked": "cameras_linked",
    "cursor": "cursor", "slice_rotation": "slice_rotation", "interpolation": "interpolation",
    "label_opacity": "label_opacity",
    "measurements": "measurements", "cutaways": "cutaways",
}


def _camera_dict(camera) -> dict[str, Any]:
    return {"position": list(camera.position), "focal_point": list(camera.focal_point),
            "view_up": list(camera.view_up), "view_angle": camera.view_angle,
            "parallel_projection": bool(camera.parallel_projection), "parallel_scale": camera.parallel_scale}


def camera_from_dict(data: dict[str, Any]):
    try:
        return Camera(tuple(data["position"]), tuple(data["focal_point"]), tuple(data["view_up"]),
                      float(data["view_angle"]), bool(data["parallel_projection"]), float(data["parallel_scale"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the session's camera is incomplete or invalid ({exc})") from None


def _transfer_dict(function: TransferFunction | None) -> dict[str, Any] | None:
    if function is None:
        return None
    return {"name": function.name, "color_points": [list(p) for p in function.color_points],
            "opacity_points": [list(p) for p in function.opacity_points], "unit_distance": function.unit_distance,
            "shading": dict(function.shading.__dict__)}


def _transfer_from_dict(data: dict[str, Any]) -> TransferFunction:
    return TransferFunction(data["name"], tuple(map(tuple, data["color_points"])),
                            tuple(map(tuple, data["opacity_points"])), float(data["unit_distance"]),
                            Shading(**data["shading"]))


def _absolute(path) -> str:
    return str(Path(path).expanduser().resolve()) if path else ""


def _source(item) -> dict[str, Any]:
    metadata = item.metadata
    entry = {"path": _absolute(metadata.get("source_path", ""))}
    if metadata.get("series_uid"):
        entry["series_uid"] = str(metadata["series_uid"])
    table = metadata.get("label_table")
    if table is not None:
        entry["labels"] = True
        entry["color_tables"] = list(table.sources)
    return entry


def model_state(model, *, cameras: list | None = None) -> dict[str, Any]:
    """The model's part of a session (JSON-ready). ``cameras``: the views' cameras (one when they are linked)."""
    if model.base is None:
        raise ValueError("there is nothing to save: open a volume first")
    data = {"volume": _source(model.base),
            "labels": [_source(item) for item in model.label_items if _opened_from_a_file(item)],
            "meshes": [_absolute(item.metadata["source_path"]) for item in model.scene.of_kind("mesh")
                       if _opened_from_a_file(item)],
            "items": []}  # the items made in the session: filled in by save_session, which writes their files
    return {
        "format": FORMAT, "version": VERSION, "data": data,
        "shown_item": model.item.name if model.item is not None else None,
        "layout": model.layout, "view_modes": list(model.view_modes),
        "view_options": [dict(options) for options in model.view_options],
        "cameras_linked": model.cameras_linked,
        "cameras": [_camera_dict(camera) for camera in (cameras or [])],
        "iso": model.iso, "preset": model.preset, "transfer_function": _transfer_dict(model.transfer_function),
        "window_level": [model.window, model.level],
        "cursor": [float(c) for c in model.cursor], "slice_rotation": np.asarray(model.slice_rotation).tolist(),
        "interpolation": model.interpolation, "label_opacity": model.label_opacity,
        "measurements": model.measurements.to_list(),
        "cutaways": model.cutaways.to_dict(),
    }


def apply_model_state(model, state: dict[str, Any]) -> None:
    """Restore what :func:`model_state` saved onto a model whose data are loaded (not recorded for undo)."""
    with model.replaying():
        shown = state.get("shown_item")
        if shown and shown in model.scene and model.scene.get(shown) is not model.item:
            model.show_item(model.scene.get(shown))
        model.set_layout(state.get("layout", model.layout))
        for index, (mode, options) in enumerate(zip(state.get("view_modes", []), state.get("view_options", []))):
            model.set_view_mode(index, mode, options or None)
        model.set_cameras_linked(bool(state.get("cameras_linked", True)))
        if model.volume is not None and state.get("iso") is not None:
            model.set_iso(float(state["iso"]))
        if model.volume is not None and state.get("transfer_function"):
            model.set_transfer_function(_transfer_from_dict(state["transfer_function"]),
                                        preset=state.get("preset") or model.preset)
        if state.get("window_level") is not None:
            model.set_window_level(*(float(v) for v in state["window_level"]))
        if state.get("cursor") is not None:
            model.set_cursor(state["cursor"])
        if state.get("slice_rotation") is not None:
            model.set_slice_rotation(state["slice_rotation"])
        model.set_interpolation(state.get("interpolation", "linear"))
        model.set_label_opacity(float(state.get("label_opacity", 0.5)))
        measurements = [Measurement.from_dict(entry) for entry in state.get("measurements", [])]
        model.measurements.replace_all([])
        for measurement in measurements:
            model.add_measurement(measurement)
        model.cutaways.restore(state.get("cutaways") or {})


# -- items made in the session -------------------------------------------------------------------------------------
ITEM_SUFFIXES = {"field": ".nrrd", "mesh": ".vtp", "tetmesh": ".vtu"}


def _opened_from_a_file(item) -> bool:
    """True for the items the user opened (saved by their path); items made in the session name the item they were
    made from (``metadata["source"]``) or carry no file of their own."""
    source = item.metadata.get("source_path", "")
    return bool(source) and "source" not in item.metadata and Path(source).expanduser().exists()


def made_items(model) -> list:
    """The scene's items that were made in the session (what :func:`save_session` writes beside the session)."""
    return [item for item in model.scene
            if item is not model.base and item.kind in ITEM_SUFFIXES and not _opened_from_a_file(item)]


def items_folder(session_path) -> Path:
    """``work.voxelscope.json`` -> ``work.voxelscope.items``: where the session's own items are written."""
    path = Path(session_path).expanduser()
    stem = path.name[: -len(".json")] if path.name.lower().endswith(".json") else path.name
    return path.with_name(stem + ".items")


def _plain(value):
    """``value`` if JSON can store it, else None (metadata: provenance numbers and names, not arrays)."""
    try:
        json.dumps(value)
    except (TypeError, ValueError):
        return None
    return value


def _write_item(item, path: Path) -> None:
    if item.kind == "field":
        save_volume(item.volume, path)
    elif item.kind == "mesh":
        write_mesh_files(item.polydata, path)
    else:
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

        with atomic_output(path) as temporary:
            write_with_vtk(vtkXMLUnstructuredGridWriter, item.grid, temporary)


def session_snapshot(model, *, cameras: list | None = None, window: dict | None = None) -> tuple[dict, list]:
    """What a session saves, taken at once on the thread that owns the model: the state (``window``: the window's
    own, under ``"ui"``) and the items made in the session (written by :func:`write_session_files`)."""
    state = model_state(model, cameras=cameras)
    if window is not None:
        state["ui"] = window
    return state, made_items(model)


def save_session(path, model, *, cameras: list | None = None, window: dict | None = None,
                 overwrite: bool = False) -> Path:
    """:func:`session_snapshot` then :func:`write_session_files`."""
    state, items = session_snapshot(model, cameras=cameras, window=window)
    return write_session_files(path, state, items, overwrite=overwrite)


def write_session_files(path, state: dict, items: list, *, overwrite: bool = False, progress=None) -> Path:
    """Write a session to ``path`` with ``items`` in :func:`items_folder` (new files each time: the previous
    session file stays valid until the new one replaces it; files it no longer names are removed after). Refuses
    an existing ``path`` unless ``overwrite``, before anything is written."""
    path = Path(path).expanduser()
    check_target(path, overwrite=overwrite)
    state = copy.deepcopy(state)
    folder = items_folder(path)
    if items:
        folder.mkdir(parents=True, exist_ok=True)
    generation = uuid.uuid4().hex[:8]
    for index, item in enumerate(items):
        if progress is not None:
            progress(index / (len(items) + 1))
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in item.name)[:60]
        file = folder / f"{index:02d}-{safe}-{generation}{ITEM_SUFFIXES[item.kind]}"
        _write_item(item, file)
        entry = {"name": item.name, "kind": item.kind, "file": f"{folder.name}/{file.name}",
                 "metadata": {k: v for k, v in item.metadata.items() if _plain(v) is not None}}
        if item.kind == "field":
            entry.update(role=item.role, units=item.volume.units, modality=item.volume.modality)
        state["data"]["items"].append(entry)
    written = write_session(path, state, overwrite=overwrite)
    kept = {entry["file"].split("/", 1)[1] for entry in state["data"]["items"]}
    if folder.is_dir():
        for stale in folder.iterdir():
            if stale.name not in kept and stale.suffix in ITEM_SUFFIXES.values():
                stale.unlink()
        if not any(folder.iterdir()):
            folder.rmdir()
    return written


def _item_file(session_path, entry: dict[str, Any]) -> Path:
    return Path(session_path).expanduser().parent / str(entry.get("file", ""))


def load_item(session_path, entry: dict[str, Any], *, progress=None):
    """One item :func:`save_session` wrote, read again as a scene item (a ValueError naming the file if not)."""
    file = _item_file(session_path, entry)
    kind, name, metadata = entry.get("kind"), str(entry.get("name", file.stem)), dict(entry.get("metadata") or {})
    metadata.setdefault("source", "")  # made in a session: saved with the next session again, never by reference
    if kind == "field":
        volume = load_volume(file)
        volume.units, volume.modality = str(entry.get("units", "")), str(entry.get("modality", ""))
        return FieldItem(name, volume=volume, role=str(entry.get("role", "mask")), metadata=metadata)
    if kind == "mesh":
        return MeshItem(name, polydata=load_mesh(file).polydata, metadata=metadata)
    if kind == "tetmesh":
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

        reader = vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(file))
        reader.Update()
        grid = reader.GetOutput()
        if grid is None or grid.GetNumberOfCells() == 0:
            raise ValueError(f"{file}: not a tetrahedral mesh Voxelscope wrote (no cells); the session's item {name} "
                             "cannot be restored")
        return TetMeshItem(name, grid=grid, metadata=metadata)
    raise ValueError(f"the session's item {name} is of an unknown kind {kind!r}")


def load_items(session_path, state: dict[str, Any]) -> list:
    """Every item made in the session, read again (for headless use; the window reads them one by one in workers)."""
    return [load_item(session_path, entry) for entry in state["data"].get("items", [])]


def write_session(path, state: dict[str, Any], *, overwrite: bool = False) -> Path:
    path = Path(path).expanduser()
    with atomic_output(path, overwrite=overwrite) as temporary:
        temporary.write_text(json.dumps(state, indent=2, default=_json_default) + "\n")
    return path


def read_session(path) -> dict[str, Any]:
    """A session file, checked: a clear one-line ValueError for anything that is not one."""
    path = Path(path).expanduser()
    try:
        state = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: no such session file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the session ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a Voxelscope session (invalid JSON at line {exc.lineno})") from None
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise ValueError(f"{path}: not a Voxelscope session file (no '\"format\": \"{FORMAT}\"')")
    if int(state.get("version", 0)) > VERSION:
        raise ValueError(f"{path}: a session of a newer Voxelscope (version {state['version']}); update Voxelscope")
    volume = state.get("data", {}).get("volume", {})
    if not volume.get("path"):
        raise ValueError(f"{path}: the session names no volume")
    tool_files = [tool.get("source", "") for tool in (state.get("cutaways") or {}).get("tools", [])
                  if tool.get("shape") == "grid"]
    item_files = [str(_item_file(path, entry)) for entry in state["data"].get("items", [])]
    missing = [p for p in [volume["path"]] + [e.get("path", "") for e in state["data"].get("labels", [])] + tool_files
               + item_files if not Path(p).exists()]
    if missing:
        raise ValueError(f"{path}: the session's data are no longer there: {', '.join(missing)}")
    return state


def _json_default(value):
    try:
        return numpy_json(value)
    except TypeError:
        raise TypeError(f"cannot store a {type(value).__name__} in a session") from None
