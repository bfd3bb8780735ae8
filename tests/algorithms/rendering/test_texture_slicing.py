"""Texture slicing: plane-box polygons against an independent polytope clip, coverage of the box, the source's
shortest-tour ordering, axis-aligned stacks, slice textures, 8-bit compositing error, agreement with VTK's GPU ray
caster and between the OpenGL and float paths, the slice polydata, the VTK filter and every documented error."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

from algorithms.common.camera import Camera, box_ray_intersection
from algorithms.common.progress import OperationCancelled
from algorithms.common.transfer import TransferTable
from algorithms.common.vtk_bridge import VTKError, image_from_array, polydata_arrays, run_algorithm
from algorithms.compare.image_metrics import psnr_foreground
from algorithms.rendering.texture_slicing import (
    MAX_POLYGON_VERTICES,
    SliceStackProp,
    SlicingRenderer,
    TextureSlicingFilter,
    axis_aligned_slices,
    default_slice_count,
    slice_polygons,
    slices_to_polydata,
)

LOW = np.array([0.0, 0.0, 0.0])
HIGH = np.array([30.0, 20.0, 12.5])  # an anisotropic box, mm
SIZE = 256  # image edge for the comparisons with VTK (pixels)


def random_camera(rng, *, parallel: bool, distance: float = 80.0) -> Camera:
    """A camera at ``distance`` mm from the box centre in a random direction, random view up."""
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    centre = 0.5 * (LOW + HIGH) + rng.uniform(-3, 3, size=3)
    return Camera(position=tuple(centre - distance * direction), focal_point=tuple(centre),
                  view_up=tuple(rng.normal(size=3)), parallel_projection=parallel, parallel_scale=30.0)


def plane_section(normal, offset, low, high):
    """Area and vertices of ``{x : normal . x = offset} & box`` by clipping the box polytope (scipy/Qhull).

    Independent of the edge intersections under test: the plane gets its own orthonormal basis, the box becomes
    six half-planes in it, an interior point comes from a linear programme (Chebyshev centre), and Qhull
    intersects the half-planes.
    """
    basis, _ = np.linalg.qr(np.column_stack([normal, [1.0, 0.3, 0.2], [0.1, 1.0, 0.7]]))
    a, b = basis[:, 1], basis[:, 2]
    origin = normal * offset
    matrix = np.vstack([np.column_stack([a, b]), -np.column_stack([a, b])])
    bound = np.concatenate([high - origin, origin - low])
    lp = linprog([0.0, 0.0, -1.0], A_ub=np.column_stack([matrix, np.linalg.norm(matrix, axis=1)]), b_ub=bound,
                 bounds=[(None, None), (None, None), (0, None)])
    assert lp.status == 0 and lp.x[2] > 0
    section = HalfspaceIntersection(np.column_stack([matrix, -bound]), lp.x[:2])
    hull = ConvexHull(section.intersections)
    return hull.volume, origin + section.intersections[hull.vertices] @ np.vstack([a, b])


def shortest_tour_order(points) -> np.ndarray:
    """The shortest closed tour through ``points`` by brute force over permutations (source 001's ordering).

    ``points`` is ``(n, 2)`` or ``(n, 3)`` with ``3 <= n <= 8`` (a plane-box polygon has at most 6); returns the
    indices along the shortest closed tour, starting at 0 (its direction is arbitrary). ``(n - 1)!`` tours are
    tried, fixing the first point; source 001 accepted the factorial cost because a plane-box polygon never has
    more than six vertices. For a convex polygon the shortest tour is its boundary (a crossing tour can be shortened
    by the triangle inequality), i.e. the angular order around the centroid. ValueError on anything else.
    """
    array = np.asarray(points, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] not in (2, 3) or not 3 <= len(array) <= 8:
        raise ValueError(f"points must have shape (n, 2) or (n, 3) with 3 <= n <= 8, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError("points must be finite")
    distances = np.linalg.norm(array[:, None] - array[None, :], axis=2)
    tours = np.array([(0, *rest) for rest in itertools.permutations(range(1, len(array)))], dtype=np.int64)
    lengths = distances[tours, np.roll(tours, -1, axis=1)].sum(axis=1)
    return tours[int(np.argmin(lengths))]


def screen_signed_areas(polygons, camera):
    """Signed area of every polygon's projection in pixels, with the screen y axis pointing up (CCW > 0)."""
    areas = []
    for index in range(len(polygons)):
        pixels = camera.project(polygons.polygon(index), 100, 100)
        x, y = pixels[:, 0], -pixels[:, 1]
        areas.append(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    return np.array(areas)


# -- geometry ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("parallel", [False, True])
def test_slice_polygons_are_the_plane_box_sections(rng, parallel):
    diagonal = np.linalg.norm(HIGH - LOW)
    tolerance = 1e-9 * diagonal
    for _ in range(60):
        camera = random_camera(rng, parallel=parallel)
        count = int(rng.integers(1, 12))
        polygons = slice_polygons(camera, LOW, HIGH, count)
        assert len(polygons) == count
        assert np.all((polygons.counts >= 3) & (polygons.counts <= MAX_POLYGON_VERTICES))
        np.testing.assert_allclose(polygons.normal, camera.direction, atol=1e-12)
        # Evenly spaced, back to front, slab midpoints between the nearest and farthest corner.
        corners = np.array([[x, y, z] for z in (LOW[2], HIGH[2]) for y in (LOW[1], HIGH[1]) for x in (LOW[0], HIGH[0])])
        heights = corners @ camera.direction
        expected = heights.max() - (np.arange(count) + 0.5) * (heights.max() - heights.min()) / count
        np.testing.assert_allclose(polygons.offsets, expected, atol=tolerance)
        for index in range(count):
            vertices = polygons.polygon(index)
            # On the plane, inside the box, on its surface.
            np.testing.assert_allclose(vertices @ polygons.normal, polygons.offsets[index], atol=tolerance)
            assert np.all(vertices >= LOW - tolerance) and np.all(vertices <= HIGH + tolerance)
            on_face = (np.abs(vertices - LOW) < tolerance) | (np.abs(vertices - HIGH) < tolerance)
            assert np.all(on_face.sum(axis=1) >= 2), "every vertex lies on a box edge (two faces)"
            # Strictly convex and counter-clockwise in the plane frame (u x v = -normal: towards the camera).
            u, v = vertices @ polygons.u_axis, vertices @ polygons.v_axis
            du, dv = np.roll(u, -1) - u, np.roll(v, -1) - v
            turns = du * np.roll(dv, -1) - dv * np.roll(du, -1)
            assert np.all(turns > 0)
            # The same section, vertices and area, from Qhull clipping the box polytope.
            area, reference = plane_section(polygons.normal, polygons.offsets[index], LOW, HIGH)
            assert len(reference) == len(vertices)
            nearest = np.linalg.norm(vertices[:, None] - reference[None], axis=2).min(axis=1)
            assert nearest.max() < 1e-7 * diagonal
            assert polygons.areas()[index] == pytest.approx(area, rel=1e-9)
        # Counter-clockwise on the screen too (projection through the camera, independent of u and v).
        assert np.all(screen_signed_areas(polygons, camera) > 0)
        # Texture coordinates are the vertices normalised to the box.
        valid = np.isfinite(polygons.vertices[..., 0])
        np.testing.assert_allclose(polygons.texture_coordinates[valid] * (HIGH - LOW) + LOW, polygons.vertices[valid])
        assert np.all(np.isnan(polygons.vertices[~valid]))


def test_planes_through_corners_and_faces_give_clean_polygons():
    cube_low, cube_high = np.zeros(3), np.ones(3)
    # Looking along (1, 1, 0) at a cube with 3 slices: the middle plane holds two vertical edges (four corners).
    camera = Camera(position=(-10.0, -10.0, 0.5), focal_point=(0.5, 0.5, 0.5), view_up=(0, 0, 1))
    polygons = slice_polygons(camera, cube_low, cube_high, 3)
    np.testing.assert_array_equal(polygons.counts, [4, 4, 4])
    middle = polygons.polygon(1)
    assert sorted(map(tuple, middle)) == [(0, 1, 0), (0, 1, 1), (1, 0, 0), (1, 0, 1)]
    assert polygons.areas()[1] == pytest.approx(math.sqrt(2))
    # Along the diagonal with 3 slices, the planes cut off triangles and a hexagon (areas from the geometry of a
    # cube section at distance t from a corner: sqrt(3)/2 t^2 up to t = 1/sqrt(3)).
    camera = Camera(position=(-10.0, -10.0, -10.0), focal_point=(0.5, 0.5, 0.5), view_up=(0, 0, 1))
    polygons = slice_polygons(camera, cube_low, cube_high, 3)
    np.testing.assert_array_equal(polygons.counts, [3, 6, 3])
    # A plane at distance t from a corner cuts an equilateral triangle of side t sqrt(6), area 3 sqrt(3) / 2 t^2;
    # the first slab midpoint lies at t = sqrt(3) / 6, and the middle plane cuts the regular hexagon of side
    # 1 / sqrt(2).
    t = math.sqrt(3) / 6
    triangle = 1.5 * math.sqrt(3) * t**2
    np.testing.assert_allclose(polygons.areas(), [triangle, 0.75 * math.sqrt(3), triangle])


@pytest.mark.parametrize("parallel", [False, True])
def test_slices_cover_the_box_for_every_ray(rng, parallel):
    """A ray meets exactly the slices whose planes lie between its box entry and exit, so every ray crossing
    the box over at least one slice distance (in depth) meets at least one slice: the union of the projected
    polygons covers the box's projection up to the half slab at the nearest and farthest corner."""
    for _ in range(12):
        camera = random_camera(rng, parallel=parallel)
        polygons = slice_polygons(camera, LOW, HIGH, 16)
        origins, directions = camera.pixel_rays(40, 40)
        origins, directions = origins.reshape(-1, 3), directions.reshape(-1, 3)
        entry, exit_ = box_ray_intersection(origins, directions, LOW, HIGH)
        crosses = exit_ > entry
        depth_in = (origins + entry[:, None] * directions) @ polygons.normal
        depth_out = (origins + exit_[:, None] * directions) @ polygons.normal
        hits = np.zeros(len(origins), dtype=np.int64)
        for index in range(len(polygons)):
            t = (polygons.offsets[index] - origins @ polygons.normal) / (directions @ polygons.normal)
            points = origins + t[:, None] * directions
            vertices = polygons.polygon(index)
            u, v = points @ polygons.u_axis, points @ polygons.v_axis
            pu, pv = vertices @ polygons.u_axis, vertices @ polygons.v_axis
            edges_u, edges_v = np.roll(pu, -1) - pu, np.roll(pv, -1) - pv
            side = edges_u[None] * (v[:, None] - pv[None]) - edges_v[None] * (u[:, None] - pu[None])
            inside = np.all(side >= -1e-9, axis=1)
            between = crosses & (depth_in <= polygons.offsets[index]) & (polygons.offsets[index] <= depth_out)
            # Away from the polygon's border (rounding), inside the polygon is the same as between entry and exit.
            clear = np.abs(side).min(axis=1) > 1e-6
            np.testing.assert_array_equal(inside[clear], between[clear])
            hits += inside
        thick = crosses & (depth_out - depth_in > polygons.slice_distance * (1 + 1e-9))
        assert thick.sum() > 100
        assert np.all(hits[thick] >= 1)
        assert np.all(hits[~crosses] == 0)


def test_angle_order_is_the_shortest_tour(rng):
    """Source 001 orders the cut points by the shortest closed tour (brute force); the angle sort gives the same
    cycle (up to its starting point and direction)."""
    checked = 0
    for _ in range(40):
        polygons = slice_polygons(random_camera(rng, parallel=True), LOW, HIGH, 5)
        for index in range(len(polygons)):
            vertices = polygons.polygon(index)
            shuffle = rng.permutation(len(vertices))
            tour = shuffle[shortest_tour_order(vertices[shuffle])]  # indices into the angle-sorted vertices
            start = int(np.argmin(tour))
            cycle = np.roll(tour, -start)
            forward = np.arange(len(vertices))
            assert np.array_equal(cycle, forward) or np.array_equal(cycle, np.r_[0, forward[:0:-1]])
            checked += 1
    assert checked == 200


def test_shortest_tour_of_a_shuffled_square():
    square = np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float)
    tour = shortest_tour_order(square)
    assert tour[0] == 0
    length = np.linalg.norm(square[tour] - square[np.roll(tour, -1)], axis=1).sum()
    assert length == pytest.approx(4.0)


@pytest.mark.parametrize(
    "direction, axis",
    [((0.2, -0.9, 0.3), 1), ((-0.8, 0.5, 0.3), 0), ((0.1, 0.2, 1.0), 2), ((0.0, 0.0, -1.0), 2), ((0.6, -0.6, 0.1), 0)],
)
def test_axis_aligned_stack_follows_the_largest_view_component(direction, axis):
    spacing = np.array([2.5, 2.0, 1.25])
    direction = np.asarray(direction) / np.linalg.norm(direction)
    centre = 0.5 * (LOW + HIGH)
    camera = Camera(position=tuple(centre - 100 * direction), focal_point=tuple(centre), view_up=(0.3, 0.4, 0.5))
    stack = axis_aligned_slices(camera, LOW, HIGH, spacing)
    assert stack.axis == axis  # the first axis wins a tie, as np.argmax does ((0.6, -0.6, 0.1): x)
    layers = int(round((HIGH[axis] - LOW[axis]) / spacing[axis])) + 1
    assert len(stack) == layers
    # Through the voxel centres, back to front along the view direction.
    positions = stack.vertices[:, 0, axis]
    np.testing.assert_allclose(np.sort(positions), LOW[axis] + np.arange(layers) * spacing[axis])
    assert np.all(np.diff(positions * np.sign(direction[axis])) < 0)
    np.testing.assert_allclose(stack.normal @ direction, abs(direction[axis]))
    assert stack.path_step == pytest.approx(spacing[axis] / abs(direction[axis]))
    other = [a for a in range(3) if a != axis]
    np.testing.assert_allclose(stack.areas(), np.prod((HIGH - LOW)[other]))
    assert np.all(stack.counts == 4)
    assert np.all(screen_signed_areas(stack, camera) > 0)


def test_default_slice_count_is_one_per_smallest_spacing():
    camera = Camera(position=(-50.0, 10.0, 6.0), focal_point=(15.0, 10.0, 6.0), view_up=(0, 0, 1))
    assert default_slice_count(camera, LOW, HIGH, (0.5, 1.0, 2.0)) == 60  # 30 mm deep along x
    diagonal = Camera(position=(-50.0, -55.0, 6.25), focal_point=(15.0, 10.0, 6.25), view_up=(0, 0, 1))
    depth = (30.0 + 20.0) / math.sqrt(2)
    assert default_slice_count(diagonal, LOW, HIGH, (0.7, 0.9, 0.8)) == math.ceil(depth / 0.7)
    volume = np.zeros((6, 9, 13), dtype=np.float32)  # box 12 x 8 x 5 mm at spacing 1 mm
    renderer = SlicingRenderer(volume, (1.0, 1.0, 1.0), TransferTable(np.zeros((2, 4)), 0.0, 1.0))
    polygons = renderer.slices_for(camera)
    assert len(polygons) == 12 and polygons.slice_distance == pytest.approx(1.0)


# -- textures and compositing -----------------------------------------------------------------------------------
def constant_volume_renderer(precision: str = "float"):
    """Axis-aligned slicing of 100 layers of a constant value along z (1 mm apart) with colour (0.2, 0.6, 1.0)
    and opacity 5/255 per layer: premultiplied texels of exactly (1, 3, 5, 5) / 255, what an 8-bit texture holds
    too."""
    table = TransferTable(np.array([[0.2, 0.6, 1.0, 5 / 255]] * 2), 0.0, 1.0, unit_distance=1.0)
    volume = np.full((100, 4, 4), 0.5, dtype=np.float32)
    return SlicingRenderer(volume, (1.0, 1.0, 1.0), table, mode="axis", precision=precision)


DOWN_Z = Camera(position=(1.5, 1.5, 200.0), focal_point=(1.5, 1.5, 0.0), view_up=(0, 1, 0),
                parallel_projection=True, parallel_scale=1.0)


def framebuffer_emulation(premultiplied, alpha, layers):
    """Back-to-front over operator with rounding to 8 bits after every layer (round half up)."""
    value = np.zeros_like(np.asarray(premultiplied, dtype=np.float64))
    for _ in range(layers):
        value = np.floor((premultiplied + (1 - alpha) * value) * 255 + 0.5) / 255
    return value


def test_eight_bit_compositing_loses_forty_percent_of_a_faint_colour():
    """Source 002 (2.4.3): a hundred slices composited in an 8-bit buffer can be off by up to 40 %."""
    alpha, layers = 5 / 255, 100
    premultiplied = np.array([1.0, 3.0, 5.0, 5.0]) / 255
    exact = premultiplied * (1 - (1 - alpha) ** layers) / alpha
    floating = constant_volume_renderer(precision="float").render(DOWN_Z, 8, 8)
    np.testing.assert_allclose(floating.rgba, np.broadcast_to(exact, (8, 8, 4)), rtol=2e-5)
    assert floating.stats["slices"] == layers and floating.stats["path_step_mm"] == 1.0
    eight_bit = constant_volume_renderer(precision="uint8").render(DOWN_Z, 8, 8)
    emulated = framebuffer_emulation(premultiplied, alpha, layers)
    np.testing.assert_allclose(eight_bit.rgba, np.broadcast_to(emulated, (8, 8, 4)), atol=1e-6)
    relative_error = (emulated - exact) / exact
    assert relative_error[0] == pytest.approx(-0.41, abs=0.01)  # red: 26 / 255 instead of 0.172


def test_opengl_framebuffer_is_eight_bit_and_blends_like_the_emulation():
    """The rasterising path in real GL gives the 8-bit emulation's values, not the float ones."""
    from app.pipeline import OffscreenScene

    scene = OffscreenScene((8, 8))
    try:
        stack = SliceStackProp(constant_volume_renderer())
        stack.attach(scene.renderer)
        stats = stack.update(DOWN_Z, 8, 8)
        assert stats["slices"] == 100 and len(stack.actors) == 100
        scene.set_camera(DOWN_Z)
        scene.render()
        frame = scene.capture()
    finally:
        scene.close()
    emulated = framebuffer_emulation(np.array([1.0, 3.0, 5.0]) / 255, 5 / 255, 100)
    np.testing.assert_allclose(frame / 255.0, np.broadcast_to(emulated, (8, 8, 3)), atol=1.01 / 255)


def test_axis_textures_are_the_classified_voxel_layers(ct_phantom):
    from app.transfer import transfer_function_for

    table = transfer_function_for(ct_phantom, "ct-bone", shading=False).to_table(ct_phantom.value_range)
    renderer = SlicingRenderer(ct_phantom.array, ct_phantom.spacing, table, mode="axis")
    camera = Camera(position=(120.0, 120.0, 500.0), focal_point=(120.0, 120.0, 100.0), view_up=(0, 1, 0))
    layout = renderer.layout(camera, 64, 64)
    corrected = table.corrected(layout.polygons.path_step)
    textures = dict(renderer.iter_textures(layout))
    assert sorted(textures) == list(range(ct_phantom.array.shape[0]))
    for index in (0, 17, 39):
        # Looking down -z the bottom layer is the farthest, so slice k is layer k; texel (p, q) is voxel (i, j)
        # (u = +x, v = +y: u x v = +z = -normal).
        expected = table.lookup(ct_phantom.array[index].astype(np.float64), corrected)
        expected[..., :3] *= expected[..., 3:]
        np.testing.assert_allclose(textures[index].rgba, expected, atol=2e-6)


def test_pixel_aligned_texels_sit_on_the_pixel_rays(ct_phantom, rng):
    from app.transfer import transfer_function_for

    table = transfer_function_for(ct_phantom, "ct-bone", shading=False).to_table(ct_phantom.value_range)
    renderer = SlicingRenderer(ct_phantom.array, ct_phantom.spacing, table, slices=8)
    box_centre = 0.5 * renderer.box_max
    for parallel in (False, True):
        camera = Camera(position=tuple(box_centre + (300.0, -250.0, 120.0)), focal_point=tuple(box_centre),
                        view_up=(0, 0, 1), parallel_projection=parallel, parallel_scale=150.0)
        width, height = 48, 36
        layout = renderer.layout(camera, width, height)
        assert layout.pixel_aligned and np.all(layout.visible)
        origins, directions = camera.pixel_rays(width, height)
        for index, texture in renderer.iter_textures(layout):
            tex_height, tex_width = texture.rgba.shape[:2]
            p, q = int(rng.integers(tex_width)), int(rng.integers(tex_height))
            centre = texture.origin + (p + 0.5) * texture.u_step + (q + 0.5) * texture.v_step
            column, row = layout.columns[index, 0] + p, layout.rows[index, 1] - 1 - q
            ray_origin, ray_direction = origins[row, column], directions[row, column]
            offset = centre - ray_origin
            assert np.linalg.norm(offset - (offset @ ray_direction) * ray_direction) < 1e-9 * 300
            np.testing.assert_allclose(texture.texture_coordinates(centre[None])[0],
                                       [(p + 0.5) / tex_width, (q + 0.5) / tex_height])


# -- against VTK and between the two compositing paths ---------------------------------------------------------------
@pytest.fixture(scope="module")
def ct_scene():
    """The small CT phantom with ct-bone (no shading), its volume-frame camera and VTK's GPU frame."""
    from app.datasets import ct_head_phantom
    from app.pipeline import default_camera
    from app.pipeline.offscreen import render_vtk_volume
    from app.transfer import transfer_function_for

    volume = ct_head_phantom(shape=(40, 96, 96), spacing=(2.5, 2.5, 5.4))
    function = transfer_function_for(volume, "ct-bone", shading=False)
    world_camera = default_camera(volume, azimuth=30, elevation=10)
    camera = world_camera.transformed(np.linalg.inv(volume.local_to_world))
    reference = render_vtk_volume(volume, world_camera, function, mapper="gpu", size=(SIZE, SIZE))
    return volume, function.to_table(volume.value_range), world_camera, camera, reference


def test_float_path_matches_vtk_gpu_at_one_slice_per_spacing(ct_scene):
    volume, table, _, camera, reference = ct_scene
    floating = SlicingRenderer(volume.array, volume.spacing, table).render(camera, SIZE, SIZE)
    assert floating.stats["slice_distance_mm"] <= min(volume.spacing)
    float_psnr = psnr_foreground(reference, floating.to_uint8())
    eight_bit = SlicingRenderer(volume.array, volume.spacing, table, precision="uint8").render(camera, SIZE, SIZE)
    uint8_psnr = psnr_foreground(reference, eight_bit.to_uint8())
    print(f"foreground PSNR against vtk-gpu: float {float_psnr:.3f} dB, uint8 {uint8_psnr:.3f} dB")
    assert float_psnr >= 26.0  # acceptance point (measured 33.3 dB)
    # ct-bone is nearly opaque per slice, so 8-bit compositing costs little here (measured 0.008 dB).
    assert float_psnr > uint8_psnr


def test_float_compositing_beats_the_eight_bit_framebuffer_with_many_faint_slices(ct_scene):
    """Many slices of low opacity: where source 002's quantisation error shows."""
    from app.pipeline.offscreen import render_vtk_volume
    from app.transfer import transfer_function_for

    volume, _, world_camera, camera, _ = ct_scene
    function = transfer_function_for(volume, "ct-soft-tissue", shading=False)
    table = function.to_table(volume.value_range)
    reference = render_vtk_volume(volume, world_camera, function, mapper="gpu", size=(SIZE, SIZE))
    scores = {}
    for precision in ("float", "uint8"):
        renderer = SlicingRenderer(volume.array, volume.spacing, table, slices=512, precision=precision)
        scores[precision] = psnr_foreground(reference, renderer.render(camera, SIZE, SIZE).to_uint8())
    print(f"512 slices, ct-soft-tissue, PSNR against vtk-gpu: float {scores['float']:.2f} dB, "
          f"uint8 {scores['uint8']:.2f} dB")
    assert scores["float"] > scores["uint8"] + 6.0  # measured 48.4 against 36.6 dB


@pytest.mark.parametrize("mode", ["view", "axis"])
def test_opengl_path_matches_the_float_path(ct_scene, mode):
    from app.pipeline import OffscreenScene

    volume, table, world_camera, camera, reference = ct_scene
    renderer = SlicingRenderer(volume.array, volume.spacing, table, mode=mode)
    floating = renderer.render(camera, SIZE, SIZE)
    scene = OffscreenScene((SIZE, SIZE))
    try:
        stack = SliceStackProp(renderer, user_matrix=volume.local_to_world)
        stack.attach(scene.renderer)
        # A first view from elsewhere: the stack is rebuilt (other slices, other order) when the camera moves.
        elsewhere = world_camera.orbited(azimuth=100.0, elevation=-30.0)
        stack.update(elsewhere.transformed(np.linalg.inv(volume.local_to_world)), SIZE, SIZE)
        scene.set_camera(elsewhere)
        scene.render()
        stats = stack.update(camera, SIZE, SIZE)
        assert stats["slices"] == floating.stats["slices"] == len(stack.actors)
        assert stack.prop.GetParts().GetNumberOfItems() == len(stack.actors)
        scene.set_camera(world_camera)
        scene.render()
        frame = scene.capture()
    finally:
        scene.close()
    agreement = psnr_foreground(floating.to_uint8(), frame)
    print(f"{mode}: OpenGL against float path {agreement:.2f} dB, OpenGL against vtk-gpu "
          f"{psnr_foreground(reference, frame):.2f} dB")
    assert agreement >= 45.0  # measured 51.9 dB (view) and 49.6 dB (axis): 8-bit textures and framebuffer


def test_slices_to_polydata_is_the_slice_stack(ct_phantom):
    spacing = ct_phantom.spacing
    low = np.array([5.0, -3.0, 2.0])
    high = low + (np.array(ct_phantom.dimensions) - 1) * np.array(spacing)
    camera = Camera(position=tuple(0.5 * (low + high) + (200.0, 150.0, 90.0)), focal_point=tuple(0.5 * (low + high)))
    expected = slice_polygons(camera, low, high, default_slice_count(camera, low, high, spacing))
    output = slices_to_polydata(expected)
    points, triangles = polydata_arrays(output)
    assert len(triangles) == int((expected.counts - 2).sum())
    np.testing.assert_allclose(points, expected.fan_triangles()[0], atol=1e-9)
    from vtkmodules.util import numpy_support

    coordinates = numpy_support.vtk_to_numpy(output.GetPointData().GetTCoords())
    np.testing.assert_allclose(coordinates * (high - low) + low, points, atol=1e-4)
    slice_index = numpy_support.vtk_to_numpy(output.GetCellData().GetArray("slice"))
    assert np.all(np.diff(slice_index) >= 0) and slice_index[-1] == len(expected) - 1
    points, triangles = polydata_arrays(slices_to_polydata(axis_aligned_slices(camera, low, high, spacing)))
    assert len(triangles) == 2 * axis_aligned_slices(camera, low, high, spacing).counts.size
    seven = slices_to_polydata(slice_polygons(camera, low, high, 7))
    assert seven.GetCellData().GetArray("slice").GetRange() == (0.0, 6.0)


def _filter_frame(slicer) -> np.ndarray:
    """The filter's output as ``(h, w, 4)`` uint8, row 0 at the top (like our renderers' frames)."""
    from vtkmodules.util import numpy_support

    output = run_algorithm(slicer)
    width, height, _ = output.GetDimensions()
    rgba = numpy_support.vtk_to_numpy(output.GetPointData().GetScalars()).reshape(height, width, 4)
    return rgba[::-1]


def _as_uint8(result) -> np.ndarray:
    return np.clip(np.rint(result.rgba * 255.0), 0, 255).astype(np.uint8)


def _slicing_filter(volume, table, camera, width: int, height: int) -> TextureSlicingFilter:
    slicer = TextureSlicingFilter()
    slicer.SetInputDataObject(image_from_array(volume.array, volume.spacing))
    slicer.SetTransferTable(table)
    slicer.SetCamera(camera)
    slicer.SetImageSize(width, height)
    return slicer


def test_filter_renders_the_float_path(ct_scene):
    """The filter's image is SlicingRenderer.render's frame for the same camera, in every mode and option."""
    volume, table, _, camera, _ = ct_scene
    slicer = _slicing_filter(volume, table, camera, 80, 64)
    cases = [
        ({}, {}),
        ({"SetNumberOfSlices": 48}, {"slices": 48}),
        ({"SetNumberOfSlices": 0, "SetSliceDistance": 3.0}, {"slice_distance": 3.0}),
        ({"SetSliceDistance": None, "SetPrecision": "uint8"}, {"precision": "uint8"}),
        ({"SetMode": "axis", "SetPrecision": "float", "SetNumberOfSlices": 48}, {"mode": "axis"}),
    ]
    for setters, options in cases:
        for name, value in setters.items():
            getattr(slicer, name)(value)
        expected = SlicingRenderer(volume.array, volume.spacing, table, **options).render(camera, 80, 64)
        frame = _filter_frame(slicer)
        assert frame.shape == (64, 80, 4) and frame[..., 3].max() > 0, options
        np.testing.assert_array_equal(frame, _as_uint8(expected), err_msg=str(options))
        assert slicer.last_stats["slices"] == expected.stats["slices"]
    # The camera is given in the image's coordinates: a shifted image with a shifted camera gives the same frame
    # (up to the rounding of the shift).
    shift = np.array([5.0, -3.0, 2.0])
    slicer.SetInputDataObject(image_from_array(volume.array, volume.spacing, origin=tuple(shift)))
    moved = np.eye(4)
    moved[:3, 3] = shift
    slicer.SetCamera(camera.transformed(moved))
    assert np.abs(_filter_frame(slicer).astype(int) - _as_uint8(expected).astype(int)).max() <= 1


def test_filter_changes_rebuild_only_what_they_must(ct_scene):
    volume, table, _, camera, _ = ct_scene
    slicer = _slicing_filter(volume, table, camera, 32, 32)
    run_algorithm(slicer)
    renderer = slicer._renderer
    stamp = slicer.GetMTime()
    slicer.SetMode("view")
    slicer.SetNumberOfSlices(0)
    slicer.SetSliceDistance(None)
    slicer.SetPrecision("float")
    assert slicer.GetMTime() == stamp  # unchanged options do not modify the filter
    slicer.SetCamera(camera.orbited(azimuth=10.0))
    run_algorithm(slicer)
    assert slicer._renderer is renderer  # a camera change renders again with the same set-up
    slicer.SetNumberOfSlices(20)
    run_algorithm(slicer)
    assert slicer._renderer is not renderer and slicer.last_stats["slices"] <= 20
    assert (slicer.GetMode(), slicer.GetNumberOfSlices(), slicer.GetSliceDistance(), slicer.GetPrecision()) == (
        "view", 20, None, "float")


def test_filter_errors_are_vtk_errors(ct_phantom):
    """Problems surface as VTK error events (VTKError from run_algorithm), never as exceptions out of RequestData."""
    image = image_from_array(ct_phantom.array, ct_phantom.spacing, origin=(5.0, -3.0, 2.0))
    table = TransferTable.from_points([(-1000, 0, 0, 0), (2000, 1, 1, 1)], [(-1000, 0.0), (2000, 0.2)],
                                      (-1000, 2000))
    slicer = TextureSlicingFilter()
    slicer.SetInputDataObject(image)
    with pytest.raises(VTKError, match="needs a camera"):
        run_algorithm(slicer)  # no camera or table yet
    slicer.SetTransferTable(table)
    slicer.SetCamera(Camera(position=(300.0, 200.0, 100.0), focal_point=(100.0, 100.0, 50.0)))
    slicer.SetImageSize(16, 16)
    slicer.SetNumberOfSlices(10)
    slicer.SetSliceDistance(2.0)
    with pytest.raises(VTKError, match="not both"):  # the renderer's ValueError, reported by the filter
        run_algorithm(slicer)
    slicer.SetSliceDistance(None)
    assert run_algorithm(slicer).GetDimensions() == (16, 16, 1)
    image.SetDirectionMatrix(0, -1, 0, 1, 0, 0, 0, 0, 1)
    image.Modified()
    with pytest.raises(VTKError, match="identity direction"):
        run_algorithm(slicer)
    with pytest.raises(ValueError, match="slice_distance"):
        slicer.SetSliceDistance(0.0)
    with pytest.raises(ValueError, match="precision"):
        slicer.SetPrecision("half")


def test_slices_behind_a_perspective_camera_are_not_drawn(ct_scene):
    volume, table, *_ = ct_scene
    renderer = SlicingRenderer(volume.array, volume.spacing, table, slices=40)
    inside = Camera(position=tuple(0.5 * renderer.box_max), focal_point=tuple(0.5 * renderer.box_max + (1, 0, 0)))
    layout = renderer.layout(inside, 32, 32)
    depth = layout.polygons.offsets - layout.polygons.normal @ np.asarray(inside.position)
    np.testing.assert_array_equal(layout.visible, depth > 0)
    result = renderer.render(inside, 32, 32)
    assert result.stats["slices"] == int((depth > 0).sum()) and np.isfinite(result.rgba).all()


def test_render_can_be_cancelled(ct_scene):
    volume, table, _, camera, _ = ct_scene
    renderer = SlicingRenderer(volume.array, volume.spacing, table)
    fractions = []

    def progress(fraction):
        fractions.append(fraction)
        raise OperationCancelled

    with pytest.raises(OperationCancelled):
        renderer.render(camera, 64, 64, progress=progress)
    assert len(fractions) == 1


# -- errors -----------------------------------------------------------------------------------------------------
def test_every_documented_error(ct_phantom):
    camera = Camera(position=(-50.0, 10.0, 6.0), focal_point=(15.0, 10.0, 6.0), view_up=(0, 0, 1))
    table = TransferTable(np.zeros((2, 4)), 0.0, 1.0)
    volume = np.zeros((4, 5, 6), dtype=np.float32)
    with pytest.raises(ValueError, match="count"):
        slice_polygons(camera, LOW, HIGH, 0)
    with pytest.raises(ValueError, match="count"):
        slice_polygons(camera, LOW, HIGH, 2.5)
    with pytest.raises(ValueError, match="positive extent"):
        slice_polygons(camera, LOW, (30.0, 0.0, 12.5), 4)
    with pytest.raises(ValueError, match="3-vectors"):
        slice_polygons(camera, (0.0, 0.0), HIGH, 4)
    with pytest.raises(ValueError, match="3-vectors"):
        axis_aligned_slices(camera, LOW, (np.inf, 1.0, 1.0), (1.0, 1.0, 1.0))
    with pytest.raises(ValueError, match="spacing"):
        axis_aligned_slices(camera, LOW, HIGH, (1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="spacing"):
        default_slice_count(camera, LOW, HIGH, (1.0, 1.0))
    with pytest.raises(TypeError, match="Camera"):
        slice_polygons("camera", LOW, HIGH, 4)
    with pytest.raises(ValueError, match="3 <= n <= 8"):
        shortest_tour_order(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="3 <= n <= 8"):
        shortest_tour_order(np.zeros((9, 3)))
    with pytest.raises(ValueError, match="3 <= n <= 8"):
        shortest_tour_order(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="finite"):
        shortest_tour_order(np.full((4, 2), np.nan))
    with pytest.raises(ValueError, match="3D volume"):
        SlicingRenderer(np.zeros((4, 4)), (1, 1, 1), table)
    with pytest.raises(ValueError, match="at least 2 voxels"):
        SlicingRenderer(np.zeros((1, 4, 4)), (1, 1, 1), table)
    with pytest.raises(ValueError, match="real-valued"):
        SlicingRenderer(np.zeros((4, 4, 4), dtype=complex), (1, 1, 1), table)
    with pytest.raises(ValueError, match="NaN"):
        SlicingRenderer(np.full((4, 4, 4), np.nan), (1, 1, 1), table)
    with pytest.raises(ValueError, match="spacing"):
        SlicingRenderer(volume, (1, -1, 1), table)
    with pytest.raises(ValueError, match="mode"):
        SlicingRenderer(volume, (1, 1, 1), table, mode="shear")
    with pytest.raises(ValueError, match="precision"):
        SlicingRenderer(volume, (1, 1, 1), table, precision="half")
    with pytest.raises(ValueError, match="slice_distance"):
        SlicingRenderer(volume, (1, 1, 1), table, slice_distance=0.0)
    with pytest.raises(ValueError, match="slices"):
        SlicingRenderer(volume, (1, 1, 1), table, slices=0)
    with pytest.raises(ValueError, match="not both"):
        SlicingRenderer(volume, (1, 1, 1), table, slice_distance=1.0, slices=10)
    with pytest.raises(ValueError, match="mode='view' only"):
        SlicingRenderer(volume, (1, 1, 1), table, mode="axis", slices=10)
    with pytest.raises(ValueError, match="texel_size"):
        SlicingRenderer(volume, (1, 1, 1), table, texel_size=-1.0)
    with pytest.raises(TypeError, match="TransferTable"):
        SlicingRenderer(volume, (1, 1, 1), "ct-bone")
    renderer = SlicingRenderer(volume, (1, 1, 1), table)
    with pytest.raises(ValueError, match="image size"):
        renderer.render(camera, 0, 10)
    with pytest.raises(ValueError, match="image size"):
        renderer.layout(camera, 10, 2.5)
    with pytest.raises(ValueError, match="4x4"):
        SliceStackProp(renderer, user_matrix=np.eye(3))
    with pytest.raises(TypeError, match="SlicingRenderer"):
        SliceStackProp(table)
    with pytest.raises(ValueError, match="image size"):
        SliceStackProp(renderer).update(camera, 10, -1)
    slicer = TextureSlicingFilter()
    with pytest.raises(ValueError, match="mode"):
        slicer.SetMode("oblique")
    with pytest.raises(ValueError, match="number of slices"):
        slicer.SetNumberOfSlices(-1)
    with pytest.raises(TypeError, match="Camera"):
        slicer.SetCamera(None)
