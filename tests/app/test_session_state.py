"""Sessions are the workbench model serialised: every piece of the model's state has its place in a session (a new
one cannot be forgotten), random states survive a save and a load unchanged, cut-away tools (grid tools by their
file) come back, and a session written by the previous version (format 1) still opens."""

from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from algorithms.fields.cutaway_tools import box_tool, cylinder_tool, plane_tool, sphere_tool
from app.cutaways import mask_tool_from_file
from app.datasets import ct_head_phantom
from app.events import Signal
from app.io import load_volume, save_volume
from app.measurements import Measurement
from app.modes import modes_for
from app.session import MODEL_FIELDS, VERSION, apply_model_state, model_state, read_session, write_session
from app.slices import PLANES
from app.workbench import INTERPOLATIONS, LAYOUTS, MAX_VIEWS, WorkbenchModel, presets_for

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def volume_path(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("session-volume")
    return save_volume(ct_head_phantom(shape=(22, 52, 52), spacing=(5.0, 5.0, 10.0)), folder / "head.nii.gz")


def test_every_piece_of_model_state_has_its_place_in_a_session():
    model = WorkbenchModel()
    state = {name for name, value in vars(model).items() if not name.startswith("_") and not isinstance(value, Signal)}
    assert state == set(MODEL_FIELDS), ("model state without a place in sessions: "
                                        f"{sorted(state - set(MODEL_FIELDS))}; gone from the model: "
                                        f"{sorted(set(MODEL_FIELDS) - state)}")


def _model_values(model: WorkbenchModel) -> dict:
    """Every piece of the model's state (:data:`MODEL_FIELDS`) in a comparable form, read from the model itself (not
    from what a session made of it: a piece a session forgot differs here)."""
    values = {}
    for name in MODEL_FIELDS:
        value = getattr(model, name)
        if name == "scene":
            value = [(item.kind, item.name) for item in value]
        elif name in ("base", "item"):
            value = None if value is None else value.name
        elif name == "transfer_function":
            value = None if value is None else dataclasses.asdict(value)
        elif name == "measurements":
            value = value.to_list()
        elif name == "cutaways":
            value = value.to_dict()
        values[name] = value
    return json.loads(json.dumps(values, default=lambda v: np.asarray(v).tolist()))


def _assert_same(a, b, where: str = "session") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for key in a:
            _assert_same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{where}: {a} != {b}"
        for index, (x, y) in enumerate(zip(a, b)):
            _assert_same(x, y, f"{where}[{index}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-9), f"{where}: {a} != {b}"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def _option_values(mode):
    """A strategy for a random subset of ``mode``'s options, each within what the option allows."""
    fields = {}
    for option in mode.options:
        allowed = option.allowed
        if allowed is not None:
            values = st.sampled_from(allowed)
        elif option.type == "bool":
            values = st.booleans()
        elif option.type == "int":
            low = int(option.minimum) if option.minimum is not None else 0
            values = st.integers(low, int(option.maximum) if option.maximum is not None else low + 64)
        elif option.type == "float":
            low = float(option.minimum) if option.minimum is not None else -100.0
            high = float(option.maximum) if option.maximum is not None else low + 200.0
            values = st.floats(low, high, allow_nan=False)
        else:
            continue
        fields[option.name] = values
    return st.fixed_dictionaries({}, optional=fields)


def _measurable(points) -> bool:
    """Points a user can measure: a distance between two points, an angle at the middle point between two others,
    each at least 1 mm from the first (a distance) or the vertex (an angle)."""
    origin = np.asarray(points[0] if len(points) == 2 else points[1])
    others = [points[1]] if len(points) == 2 else [points[0], points[2]]
    return all(np.linalg.norm(np.subtract(other, origin)) > 1.0 for other in others)


def _accepted(mode, options) -> bool:
    """Options a mode takes together (some exclude each other, such as a slice count and a slice distance)."""
    try:
        mode.resolve_options(options)
    except ValueError:
        return False
    return True


@st.composite
def _tools(draw, bounds):
    low, high = np.asarray(bounds[0::2]), np.asarray(bounds[1::2])
    fraction = st.floats(0.0, 1.0)
    centre = tuple(float(v) for v in low + (high - low) * np.array([draw(fraction) for _ in range(3)]))
    rotation = tuple(draw(st.floats(-180.0, 180.0)) for _ in range(3))
    size = st.floats(1.0, 200.0)
    mode = draw(st.sampled_from(("remove", "keep")))
    shape = draw(st.sampled_from(("box", "sphere", "cylinder", "plane")))
    if shape == "box":
        tool = box_tool(centre, [draw(size) for _ in range(3)], rotation, mode=mode)
    elif shape == "sphere":
        tool = sphere_tool(centre, draw(size), mode=mode)
    elif shape == "cylinder":
        tool = cylinder_tool(centre, draw(size), draw(size), rotation, mode=mode)
    else:
        normal = [draw(st.floats(-1.0, 1.0)) for _ in range(3)]
        if np.linalg.norm(normal) < 1e-3:
            normal = [0.0, 0.0, 1.0]
        tool = plane_tool(centre, normal, mode=mode)
    return tool.moved(visible=draw(st.booleans()))


@st.composite
def _edits(draw, volume):
    """A list of edits a user could make, as (method name, arguments) to replay on a model."""
    lo, hi = volume.value_range
    bounds = volume.world_bounds
    model = WorkbenchModel()
    usable = modes_for(model.set_volume(volume))
    edits = [("set_layout", (draw(st.sampled_from(sorted(LAYOUTS))),))]
    for index in range(MAX_VIEWS):
        mode = draw(st.sampled_from(usable))
        options = draw(_option_values(mode).filter(functools.partial(_accepted, mode)))
        edits.append(("set_view_mode", (index, mode.name, options)))
    edits.append(("set_cameras_linked", (draw(st.booleans()),)))
    edits.append(("set_preset", (draw(st.sampled_from(presets_for(volume))),)))
    values = sorted(draw(st.lists(st.floats(lo, hi), min_size=2, max_size=5, unique=True)))
    edits.append(("set_opacity_points", ([(v, draw(st.floats(0.0, 1.0))) for v in values],)))
    edits.append(("set_shading", (), {"enabled": draw(st.booleans()), "ambient": draw(st.floats(0.0, 1.0)),
                                      "specular_power": draw(st.floats(1.0, 100.0))}))
    edits.append(("set_iso", (draw(st.floats(lo, hi)),)))
    edits.append(("set_window_level", (draw(st.floats(1.0, 4000.0)), draw(st.floats(-1000.0, 1000.0)))))
    edits.append(("set_cursor", ([draw(st.floats(bounds[2 * a] - 20, bounds[2 * a + 1] + 20)) for a in range(3)],)))
    for _ in range(draw(st.integers(0, 2))):
        edits.append(("rotate_slices", (draw(st.sampled_from(PLANES)), draw(st.floats(-90.0, 90.0)))))
    edits.append(("set_interpolation", (draw(st.sampled_from(INTERPOLATIONS)),)))
    edits.append(("set_label_opacity", (draw(st.floats(0.0, 1.0)),)))
    point = st.tuples(*(st.floats(bounds[2 * a], bounds[2 * a + 1]) for a in range(3)))
    for _ in range(draw(st.integers(0, 3))):
        kind = draw(st.sampled_from(("distance", "angle")))
        count = 2 if kind == "distance" else 3
        points = draw(st.lists(point, min_size=count, max_size=count).filter(_measurable))
        edits.append(("add_measurement", (Measurement(kind, points=points),)))
    tools = draw(st.lists(_tools(bounds), max_size=3))
    edits.append(("cutaways.set_tools", (tools,)))
    edits.append(("cutaways.set_evaluation", (draw(st.sampled_from(("binary", "distance"))),)))
    return edits


def _replay(model: WorkbenchModel, edits) -> None:
    for name, args, *kwargs in edits:
        target = model
        for part in name.split(".")[:-1]:
            target = getattr(target, part)
        getattr(target, name.split(".")[-1])(*args, **(kwargs[0] if kwargs else {}))


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(data=st.data())
def test_random_states_survive_a_save_and_a_load(data, volume_path, tmp_path):
    model = WorkbenchModel()
    model.set_volume(load_volume(volume_path))
    _replay(model, data.draw(_edits(model.volume), label="edits"))
    saved = model_state(model)
    path = write_session(tmp_path / "random.voxelscope.json", saved, overwrite=True)

    restored = WorkbenchModel()
    loaded = read_session(path)
    restored.set_volume(load_volume(loaded["data"]["volume"]["path"]))
    apply_model_state(restored, loaded)
    _assert_same(_model_values(model), _model_values(restored), "model")


def test_cut_away_tools_come_back_with_a_mask_tool_read_again_from_its_file(volume_path, tmp_path):
    from app.volume import Volume

    mask = np.zeros((10, 12, 14), np.uint8)
    mask[3:7, 4:9, 5:10] = 1
    mask_file = save_volume(Volume(mask, spacing=(2.0, 2.0, 2.0), origin=(-20.0, -30.0, 10.0)),
                            tmp_path / "mask.nii.gz")
    model = WorkbenchModel()
    model.set_volume(load_volume(volume_path))
    grid = mask_tool_from_file(str(mask_file), mode="keep").moved(centre=(5.0, 6.0, 7.0))
    model.cutaways.set_tools([box_tool((1, 2, 3), (40, 50, 60), (10, 20, 30)), grid])
    model.cutaways.set_evaluation("distance")
    session = write_session(tmp_path / "tools.voxelscope.json", model_state(model))

    restored = WorkbenchModel()
    restored.set_volume(load_volume(volume_path))
    apply_model_state(restored, read_session(session))
    box, again = restored.cutaways.tools
    assert restored.cutaways.evaluation == "distance"
    assert box.shape == "box" and box.size == (40.0, 50.0, 60.0)
    np.testing.assert_allclose(box.matrix, model.cutaways.tools[0].matrix)
    assert again.shape == "grid" and again.mode == "keep" and again.role == "mask"
    np.testing.assert_allclose(again.matrix, grid.matrix)
    np.testing.assert_array_equal(again.values, grid.values)
    np.testing.assert_allclose(again.centre, (5.0, 6.0, 7.0))

    mask_file.unlink()
    with pytest.raises(ValueError, match="no longer there: .*mask.nii.gz"):
        read_session(session)


def test_a_session_of_the_previous_version_still_opens(volume_path, tmp_path):
    text = (DATA / "session-v1.voxelscope.json").read_text().replace("{VOLUME}", str(volume_path))
    assert json.loads(text)["version"] == 1 < VERSION
    (tmp_path / "old.voxelscope.json").write_text(text)
    state = read_session(tmp_path / "old.voxelscope.json")
    model = WorkbenchModel()
    model.set_volume(load_volume(volume_path))
    model.cutaways.set_tools([sphere_tool((0, 0, 0), 10.0)])  # a version 1 session has none: they go
    apply_model_state(model, state)
    assert model.layout == "1x2" and model.view_modes[1] == "raymarch" and model.view_options[1] == {"samples": 20}
    assert model.iso == 500.0 and model.preset == "ct-skin" and (model.window, model.level) == (1800.0, 400.0)
    assert model.interpolation == "nearest" and not np.allclose(model.slice_rotation, np.eye(3))
    assert [m.results["value"] for m in model.measurements] == [pytest.approx(5.0)]
    assert model.cutaways.tools == [] and model.cutaways.evaluation == "binary"


def _made_items(volume):
    """A distance field on an oblique grid, a surface and a tetrahedral mesh, as operations make them."""
    import pyvista as pv

    from algorithms.fields.cutaway_tools import rotation_matrix
    from app.scene import FieldItem, MeshItem, TetMeshItem
    from app.volume import Volume

    values = np.random.default_rng(3).normal(size=(9, 10, 11)).astype(np.float32)
    field = Volume(values, spacing=(1.5, 2.0, 2.5), origin=(-10.0, 5.0, 20.0), direction=rotation_matrix((10, 0, 25)),
                   units="mm")
    sphere = pv.Sphere(radius=20.0, center=(5.0, -3.0, 40.0))
    grid = pv.ImageData(dimensions=(3, 3, 3), spacing=(4.0, 4.0, 4.0)).triangulate()
    return [FieldItem("distance to skull", volume=field, role="distance", metadata={"source": "skull.stl"}),
            MeshItem("head surface", polydata=sphere, metadata={"source": volume.name, "iso": 300.0}),
            TetMeshItem("head tetrahedra", grid=grid, metadata={"source": volume.name})]


def test_items_made_in_the_session_are_written_beside_it_and_read_back_where_they_were(volume_path, tmp_path):
    from app.session import items_folder, load_items, save_session

    model = WorkbenchModel()
    model.set_volume(load_volume(volume_path))
    field, surface, tetrahedra = made = _made_items(model.base)
    for item in made:
        model.scene.add(item)
    model.show_item(field)
    model.set_view_mode(0, "raymarch")
    path = save_session(tmp_path / "work.voxelscope.json", model)
    folder = items_folder(path)
    assert folder.name == "work.voxelscope.items" and len(list(folder.iterdir())) == 3
    state = read_session(path)
    assert [entry["name"] for entry in state["data"]["items"]] == [item.name for item in made]
    assert state["data"]["meshes"] == [] and state["data"]["labels"] == []

    restored = WorkbenchModel()
    restored.set_volume(load_volume(state["data"]["volume"]["path"]))
    for item in load_items(path, state):
        restored.scene.add(item)
    apply_model_state(restored, state)
    assert restored.item.name == "distance to skull" and restored.view_modes[0] == "raymarch"
    again = restored.scene.get("distance to skull")
    assert again.role == "distance" and again.volume.units == "mm"
    np.testing.assert_array_equal(again.volume.array, field.volume.array)
    np.testing.assert_allclose(again.volume.local_to_world, field.volume.local_to_world, atol=1e-9)
    np.testing.assert_allclose(restored.scene.get("head surface").bounds, surface.bounds, atol=1e-5)
    grid = restored.scene.get("head tetrahedra").grid
    assert grid.GetNumberOfCells() == tetrahedra.grid.GetNumberOfCells()
    np.testing.assert_allclose(grid.GetBounds(), tetrahedra.grid.GetBounds())

    # A second save replaces the files (new names: the old session stays valid until the new one is in place);
    # without overwrite nothing is written at all.
    before = sorted(p.name for p in folder.iterdir())
    with pytest.raises(Exception, match="already exists"):
        save_session(path, restored)
    assert sorted(p.name for p in folder.iterdir()) == before
    save_session(path, restored, overwrite=True)
    after = sorted(p.name for p in folder.iterdir())
    assert len(after) == 3 and not set(after) & set(before)
    next(folder.iterdir()).unlink()
    with pytest.raises(ValueError, match="no longer there"):
        read_session(path)
