"""Workbench sessions: one JSON file with the data paths, the layout, each view's mode and options, the camera,
the isovalue, the transfer function, window/level, the slice cursor and its oblique rotation, the measurements, and
the window's own layout (dock arrangement, window geometry, which view is enlarged), so that a session saved today
opens tomorrow as it was. ``voxelscope gui --session FILE`` and File > Open session read it.

The model part is Qt-free (:func:`model_state`, :func:`apply_model_state`); the window adds its own keys under
``"ui"`` (opaque to this module). Files are written atomically and never replaced without being asked.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .io.atomic import numpy_json
from .measurements import Measurement
from .transfer import Shading, TransferFunction

FORMAT = "voxelscope-session"
VERSION = 1


def _camera_dict(camera) -> dict[str, Any]:
    return {"position": list(camera.position), "focal_point": list(camera.focal_point),
            "view_up": list(camera.view_up), "view_angle": camera.view_angle,
            "parallel_projection": bool(camera.parallel_projection), "parallel_scale": camera.parallel_scale}


def camera_from_dict(data: dict[str, Any]):
    from algorithms.common.camera import Camera

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


def _source(item) -> dict[str, Any]:
    metadata = item.metadata
    entry = {"path": str(metadata.get("source_path", ""))}
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
            "labels": [_source(item) for item in model.label_items],
            "meshes": [str(item.metadata.get("source_path", "")) for item in model.scene.of_kind("mesh")
                       if item.metadata.get("source_path")]}
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
    }


def apply_model_state(model, state: dict[str, Any]) -> None:
    """Restore what :func:`model_state` saved onto a model whose data are loaded (not recorded for undo)."""
    with model.replaying():
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


def write_session(path, state: dict[str, Any], *, overwrite: bool = False) -> Path:
    from .io.atomic import atomic_output

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
    missing = [p for p in [volume["path"]] + [e.get("path", "") for e in state["data"].get("labels", [])]
               if not Path(p).exists()]
    if missing:
        raise ValueError(f"{path}: the session's data are no longer there: {', '.join(missing)}")
    return state


def _json_default(value):
    try:
        return numpy_json(value)
    except TypeError:
        raise TypeError(f"cannot store a {type(value).__name__} in a session") from None
