"""Surface views are lit so that axis-aligned faces can be told apart from every standard view (issue 17, item 3).

The test object is a block pierced by a square tunnel along the view axis: from each standard view the front
faces and the four walls of the tunnel seen end-on are in view, five orientations of voxel faces. A second render of the
same surface with one flat colour per face orientation and no lighting labels every pixel; the lit picture must
give each orientation its own brightness (at least ``MIN_STEP`` grey levels apart) without blowing any out. VTK's
headlight alone fails this (faces square to the view at full strength, walls almost black), which shows the test
can fail. The lighting is the same for every surface mode and is handed back when a view switches to a volume mode.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.modes import get_mode
from app.pipeline.cameras import STANDARD_VIEWS, default_camera
from app.pipeline.headless import RenderSettings, render_item, view_inputs
from app.pipeline.jobs import ImmediateRunner
from app.pipeline.offscreen import OffscreenScene
from app.pipeline.props import SURFACE_LIGHTS, surface_actor
from app.pipeline.view import ViewPipeline
from app.scene import VolumeItem
from app.volume import Volume

SIZE = (256, 256)
MIN_STEP = 10  # grey levels between the mean brightness of two face orientations
MIN_PIXELS = 150  # an orientation counts when this many of its pixels are in view (after erosion)
LABELS = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [0, 255, 255], [255, 0, 255]], np.uint8)


#: Array axis (k, j, i) along which each standard view looks (identity direction: i = x, j = y, k = z, LPS).
VIEW_AXIS = {"anterior": 1, "posterior": 1, "left": 2, "right": 2, "superior": 0, "inferior": 0}


@pytest.fixture(scope="module", autouse=True)
def warm_window():
    """The first off-screen window of a process can capture an empty frame (Mesa under Xvfb); open one first."""
    scene = OffscreenScene((16, 16))
    scene.render()
    scene.close()


def tunnel(view: str) -> VolumeItem:
    """A 40-voxel block with a 28-voxel square tunnel through it along the view axis."""
    block = np.zeros((48, 48, 48), np.uint8)
    block[4:44, 4:44, 4:44] = 1
    hole = [slice(10, 38)] * 3
    hole[VIEW_AXIS[view]] = slice(None)
    block[tuple(hole)] = 0
    return VolumeItem("tunnel", volume=Volume(block, spacing=(1.0, 1.0, 1.0)))


def orientation_labels(item, polydata, view: str) -> np.ndarray:
    """Per pixel: which of the six face orientations (0..5, by the dominant axis and sign of the face normal,
    patient coordinates) is in front, or -1; rendered without lighting, one flat colour per orientation."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals

    normals = vtkPolyDataNormals()
    normals.SetInputData(polydata)
    normals.ComputeCellNormalsOn()
    normals.ComputePointNormalsOff()
    normals.SplittingOff()
    normals.ConsistencyOff()
    normals.AutoOrientNormalsOff()
    normals.Update()
    labelled = normals.GetOutput()
    cell_normals = numpy_support.vtk_to_numpy(labelled.GetCellData().GetNormals())
    world = cell_normals @ item.local_to_world[:3, :3].T
    axis = np.argmax(np.abs(world), axis=1)
    label = 2 * axis + (world[np.arange(len(world)), axis] < 0)
    colours = numpy_support.numpy_to_vtk(LABELS[label], deep=True)
    colours.SetName("label")
    labelled.GetCellData().SetScalars(colours)
    actor = surface_actor(labelled, item.local_to_world)
    mapper = actor.GetMapper()
    mapper.ScalarVisibilityOn()
    mapper.SetScalarModeToUseCellData()
    mapper.SetColorModeToDirectScalars()
    prop = actor.GetProperty()
    prop.LightingOff()
    prop.SetAmbient(1.0)  # unlit colour = (ambient + diffuse) x colour: make it exactly the label
    prop.SetDiffuse(0.0)
    prop.SetSpecular(0.0)
    scene = OffscreenScene(SIZE)
    try:
        scene.add(actor)
        scene.set_camera(default_camera(item, view=view, aspect=SIZE[0] / SIZE[1]))
        scene.render()
        image = scene.capture()
    finally:
        scene.close()
    result = np.full(image.shape[:2], -1)
    for index, colour in enumerate(LABELS):
        result[np.all(image == colour, axis=2)] = index
    return result


def eroded(mask: np.ndarray) -> np.ndarray:
    """Pixels whose four neighbours have the same label (away from edges, where two renders may differ)."""
    inner = mask.copy()
    inner[1:] &= mask[:-1]
    inner[:-1] &= mask[1:]
    inner[:, 1:] &= mask[:, :-1]
    inner[:, :-1] &= mask[:, 1:]
    return inner


def brightness_by_orientation(image: np.ndarray, labels: np.ndarray) -> dict[int, tuple[float, float]]:
    """Mean brightness (mean of R, G, B) and the share of clipped pixels (a channel at 255) per orientation."""
    luminance = image.astype(np.float64).mean(axis=2)
    clipped = (image == 255).any(axis=2)
    result = {}
    for index in range(6):
        mask = eroded(labels == index)
        if np.count_nonzero(mask) >= MIN_PIXELS:
            result[index] = (float(luminance[mask].mean()), float(clipped[mask].mean()))
    return result


def distinguishable(measured: dict[int, tuple[float, float]]) -> bool:
    means = sorted(mean for mean, _ in measured.values())
    return (len(means) >= 3 and min(np.diff(means)) >= MIN_STEP and means[0] >= 25
            and all(clipped < 0.01 for _, clipped in measured.values()))


@pytest.mark.parametrize("mode", ["voxel-faces", "tower", "marching-cubes"])
@pytest.mark.parametrize("view", list(STANDARD_VIEWS))
def test_face_orientations_are_distinguishable_from_every_standard_view(mode, view):
    tunnels = tunnel(view)
    surface = get_mode(mode).extract(tunnels, 0.5).polydata
    labels = orientation_labels(tunnels, surface, view)
    image = render_item(tunnels, RenderSettings(mode=get_mode(mode), view=view, size=SIZE, iso=0.5)).image
    measured = brightness_by_orientation(image, labels)
    assert len(measured) == 5, measured  # the front faces and the four walls of the tunnel seen end-on
    assert distinguishable(measured), measured


def test_the_headlight_alone_fails_the_same_test():
    tunnels = tunnel("anterior")
    surface = get_mode("voxel-faces").extract(tunnels, 0.5).polydata
    labels = orientation_labels(tunnels, surface, "anterior")
    scene = OffscreenScene(SIZE)
    try:
        scene.add(surface_actor(surface, tunnels.local_to_world, color=(0.85, 0.85, 0.85), flat=True))
        scene.set_camera(default_camera(tunnels, view="anterior", aspect=1.0))
        scene.render()  # VTK's automatic headlight
        scene.render()
        image = scene.capture()
    finally:
        scene.close()
    measured = brightness_by_orientation(image, labels)
    assert len(measured) == 5 and not distinguishable(measured), measured


def lights_of(renderer) -> list[tuple]:
    collection = renderer.GetLights()
    return [(round(light.GetIntensity(), 6), tuple(round(v, 6) for v in light.GetPosition()),
             light.GetLightType()) for light in (collection.GetItemAsObject(i)
                                                 for i in range(collection.GetNumberOfItems()))]


def test_same_lights_in_every_surface_mode_and_handed_back():
    from app.modes import mode_names

    tunnels = tunnel("anterior")
    scene = OffscreenScene((64, 64))
    pipeline = ViewPipeline(scene.renderer, ImmediateRunner(), lambda: (64, 64))
    try:
        pipeline.set_inputs(view_inputs(tunnels, iso=0.5), get_mode("vtk-gpu"))
        scene.render()
        before = lights_of(scene.renderer)  # VTK's automatic headlight
        seen = {}
        for mode in mode_names(input="volume", output="surface") + ["marching-cubes-vs-flying-edges"]:
            pipeline.set_mode(get_mode(mode))
            scene.render()
            seen[mode] = lights_of(scene.renderer)
            assert scene.renderer.GetUseSSAO()
        assert len({tuple(lights) for lights in seen.values()}) == 1
        assert len(next(iter(seen.values()))) == len(SURFACE_LIGHTS)
        pipeline.set_mode(get_mode("vtk-gpu"))
        scene.render()
        assert lights_of(scene.renderer) == before and not scene.renderer.GetUseSSAO()
    finally:
        pipeline.shutdown()
        scene.close()


def test_voxel_steps_show_from_a_standard_view():
    """From the front nearly every visible voxel face of a head faces the camera, so no directional light can
    separate the steps; ambient occlusion darkens each step's edge. Share of the silhouette's pixels on an edge
    (brightness jump of more than 6 grey levels to a neighbour): with the surface lighting against without. The
    head is the CT phantom on a grid of 1.1 x 1.1 x 3 mm voxels, so that the steps are larger than a pixel."""
    from app.datasets import ct_head_phantom

    item = VolumeItem("ct", volume=ct_head_phantom((88, 256, 256)))

    def edge_share(image):
        grey = image.astype(np.float64).mean(axis=2)
        inside = eroded(eroded(grey > 10))
        jump = np.maximum(np.abs(np.diff(grey, axis=0, prepend=grey[:1])), np.abs(np.diff(grey, axis=1,
                                                                                          prepend=grey[:, :1])))
        return float(np.mean(jump[inside] > 6))

    lit = render_item(item, RenderSettings(mode=get_mode("voxel-faces"), size=SIZE)).image
    surface = render_item(item, RenderSettings(mode=get_mode("voxel-faces"), size=SIZE))  # same again: deterministic
    assert np.array_equal(lit, surface.image)

    polydata = get_mode("voxel-faces").extract(item, 300.0).polydata
    scene = OffscreenScene(SIZE)
    try:
        scene.add(surface_actor(polydata, item.local_to_world, flat=True))
        scene.set_camera(default_camera(item, view="anterior", aspect=1.0))
        scene.render()
        scene.render()
        plain = scene.capture()
    finally:
        scene.close()
    assert edge_share(plain) < 0.02 and edge_share(lit) > 0.1, (edge_share(plain), edge_share(lit))
