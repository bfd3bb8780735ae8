"""VTK props of a view: surface actors, distance-coloured surfaces with their colour bar, VTK volume mappers, and
our software renderers' frames shown as the renderer's background.

Every view (a window view or the command line's off-screen scene) builds its props here, so a mode looks the same
on screen and in a PNG.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkLookupTable
from vtkmodules.vtkCommonDataModel import vtkImageData

from algorithms.common.vtk_bridge import vtk_matrix
from algorithms.references.vtk_volume_mappers import volume_prop as vtk_volume_prop

SURFACE_MATERIAL = {"ambient": 0.15, "diffuse": 0.8, "specular": 0.2, "specular_power": 20.0}

#: The lights of every surface view, fixed to the camera: name, elevation and azimuth (degrees, seen from the camera:
#: up and right are positive) and intensity. A key light above and to the left of the view axis, a fill light below
#: and to the right, and a weak headlight. With VTK's headlight alone, faces square to the view are lit at full
#: strength (diffuse plus a specular highlight: blown out) and faces along it not at all, so a voxel surface seen from
#: a standard view is a flat silhouette. With these lights the six orientations of voxel faces come out at different,
#: unsaturated brightnesses from every standard view (with the material above, in shares of the surface colour: facing
#: the camera 0.85, up 0.54, left 0.41, right 0.34, down 0.27; ``tests/app/test_surface_lighting.py`` measures it),
#: and smooth surfaces are modelled by a key light off the view axis. Every surface mode uses them, so modes stay
#: comparable, on screen and in ``voxelscope render`` alike.
SURFACE_LIGHTS = (
    ("key", 40.0, -35.0, 0.75),
    ("fill", -25.0, 50.0, 0.35),
    ("head", 0.0, 0.0, 0.2),
)


def surface_lights() -> list:
    """``vtkLight`` objects for :data:`SURFACE_LIGHTS` (camera lights: they turn with the camera)."""
    from vtkmodules.vtkRenderingCore import vtkLight

    lights = []
    for _, elevation, azimuth, intensity in SURFACE_LIGHTS:
        light = vtkLight()
        light.SetLightTypeToCameraLight()  # camera coordinates: camera at (0, 0, 1), looking at the origin, y up
        light.PositionalOff()
        e, a = np.radians(elevation), np.radians(azimuth)
        light.SetPosition(float(np.cos(e) * np.sin(a)), float(np.sin(e)), float(np.cos(e) * np.cos(a)))
        light.SetFocalPoint(0.0, 0.0, 0.0)
        light.SetColor(1.0, 1.0, 1.0)
        light.SetIntensity(intensity)
        lights.append(light)
    return lights


#: Screen-space ambient occlusion of surface views, in units of the surface's detail size (the largest voxel spacing
#: of the volume it came from): the radius of the hemisphere sampled around each pixel and the depth bias. Directional
#: lights give every face of one orientation the same brightness, and from a standard view almost every visible voxel
#: face faces the camera, so the steps of a voxel surface only show by their occlusion; smooth surfaces get the usual
#: darkening of creases.
SSAO_RADIUS = 2.0
SSAO_BIAS = 0.05
SSAO_KERNEL = 64


class SurfaceLighting:
    """Puts :func:`surface_lights` and ambient occlusion on a renderer for as long as a surface is shown, then gives
    back what was there (a volume mode's lights, or VTK's automatic headlight, and no occlusion)."""

    def __init__(self) -> None:
        self._renderer = None
        self._saved: list = []
        self._automatic = True
        self._ssao: tuple = ()
        self.lights: list = []

    def install(self, renderer, detail_mm: float = 1.0) -> None:
        """Light ``renderer`` for surfaces whose detail (voxel size) is ``detail_mm``."""
        if self._renderer is not renderer:
            self.remove()
            collection = renderer.GetLights()
            self._saved = [collection.GetItemAsObject(i) for i in range(collection.GetNumberOfItems())]
            self._automatic = bool(renderer.GetAutomaticLightCreation())
            self._ssao = (renderer.GetUseSSAO(), renderer.GetSSAORadius(), renderer.GetSSAOBias(),
                          renderer.GetSSAOKernelSize(), renderer.GetSSAOBlur())
            renderer.RemoveAllLights()
            renderer.AutomaticLightCreationOff()
            self.lights = surface_lights()
            for light in self.lights:
                renderer.AddLight(light)
            self._renderer = renderer
        detail = float(detail_mm) if np.isfinite(detail_mm) and detail_mm > 0 else 1.0
        renderer.UseSSAOOn()
        renderer.SetSSAORadius(SSAO_RADIUS * detail)
        renderer.SetSSAOBias(SSAO_BIAS * detail)
        renderer.SetSSAOKernelSize(SSAO_KERNEL)
        renderer.SSAOBlurOn()

    def remove(self) -> None:
        renderer = self._renderer
        if renderer is None:
            return
        for light in self.lights:
            renderer.RemoveLight(light)
        for light in self._saved:
            renderer.AddLight(light)
        renderer.SetAutomaticLightCreation(self._automatic)
        use, radius, bias, kernel, blur = self._ssao
        renderer.SetUseSSAO(use)
        renderer.SetSSAORadius(radius)
        renderer.SetSSAOBias(bias)
        renderer.SetSSAOKernelSize(kernel)
        renderer.SetSSAOBlur(blur)
        self._renderer, self._saved, self._ssao, self.lights = None, [], (), []


def surface_color(units: str, iso: float) -> tuple[float, float, float]:
    """A material colour for an isosurface: skin, soft tissue or bone for CT by the isovalue (HU), grey otherwise."""
    if units == "HU":
        if iso < -200:
            return (0.93, 0.74, 0.62)  # skin
        if iso < 150:
            return (0.85, 0.45, 0.40)  # soft tissue
        return (0.91, 0.86, 0.72)  # bone
    return (0.85, 0.85, 0.85)


def surface_actor(polydata, local_to_world=None, *, color=(0.9, 0.85, 0.75), flat: bool = False,
                  opacity: float = 1.0, scalars: str | None = None, scalar_range=None, lookup_table=None):
    """A ``vtkActor`` for a surface; ``local_to_world`` (4x4) places a surface built in a volume's frame."""
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

    mapper = vtkPolyDataMapper()
    mapper.SetInputData(polydata)
    if scalars:
        mapper.SetScalarModeToUsePointFieldData()
        mapper.SelectColorArray(scalars)
        mapper.ScalarVisibilityOn()
        if scalar_range is not None:
            mapper.SetScalarRange(*scalar_range)
        if lookup_table is not None:
            mapper.SetLookupTable(lookup_table)
    else:
        mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*color)
    prop.SetOpacity(opacity)
    prop.SetAmbient(SURFACE_MATERIAL["ambient"])
    prop.SetDiffuse(SURFACE_MATERIAL["diffuse"])
    prop.SetSpecular(SURFACE_MATERIAL["specular"])
    prop.SetSpecularPower(SURFACE_MATERIAL["specular_power"])
    if flat:
        prop.SetInterpolationToFlat()
    if local_to_world is not None:
        actor.SetUserMatrix(vtk_matrix(local_to_world))
    return actor


#: Colour bars: labels and title in points (readable at any view size, not scaled with the bar).
LEGEND_FONT_SIZE = 14
LEGEND_LABELS = 5


def legend_bar(lookup_table, title: str, *, above_range: str | None = None):
    """A vertical ``vtkScalarBarActor`` at the right of the view with readable, fixed-size labels (``%.3g``: 0,
    0.047, 0.094, ...) at five evenly spaced values of the lookup table's range; ``above_range`` labels a swatch for
    values beyond the range."""
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    bar = vtkScalarBarActor()
    bar.SetLookupTable(lookup_table)
    bar.SetTitle(title)
    bar.SetNumberOfLabels(LEGEND_LABELS)
    bar.SetLabelFormat("%.3g")
    bar.UnconstrainedFontSizeOn()
    for text in (bar.GetLabelTextProperty(), bar.GetTitleTextProperty()):
        text.SetFontSize(LEGEND_FONT_SIZE)
        text.SetColor(1.0, 1.0, 1.0)
        text.ShadowOn()
        text.BoldOff()
        text.ItalicOff()
    bar.SetMaximumWidthInPixels(120)
    bar.SetBarRatio(0.25)
    bar.SetWidth(0.16)
    bar.SetHeight(0.6)
    bar.SetPosition(0.80, 0.2)
    if above_range:
        bar.DrawAboveRangeSwatchOn()
        bar.SetAboveRangeAnnotation(above_range)
    return bar


def distance_colors(tolerance_mm: float):
    """The fixed-meaning colours of a distance view: blue at 0, white at the tolerance, red at twice it and beyond."""
    from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

    top = 2.0 * tolerance_mm
    colors = vtkColorTransferFunction()
    colors.AddRGBPoint(0.0, 0.23, 0.30, 0.75)
    colors.AddRGBPoint(tolerance_mm, 0.87, 0.87, 0.87)
    colors.AddRGBPoint(top, 0.71, 0.02, 0.15)
    colors.SetAboveRangeColor(0.71, 0.02, 0.15)
    colors.UseAboveRangeColorOn()
    colors.SetRange(0.0, top)
    return colors


def distance_actor(polydata, local_to_world, array: str, *, tolerance_mm: float):
    """A surface coloured by a point array of distances (mm) on a fixed scale: blue at 0, white at
    ``tolerance_mm``, red at twice it and beyond, whatever the distances are. Returns the actor and its colour bar
    (0 to twice the tolerance, in mm)."""
    if not (np.isfinite(tolerance_mm) and tolerance_mm > 0):
        raise ValueError(f"the legend's tolerance must be a positive distance in mm, got {tolerance_mm}")
    colors = distance_colors(tolerance_mm)
    actor = surface_actor(polydata, local_to_world, scalars=array, scalar_range=(0.0, 2.0 * tolerance_mm),
                          lookup_table=colors)
    bar = legend_bar(colors, "distance\n(mm)", above_range=f"> {2.0 * tolerance_mm:.3g}")
    return actor, bar


def difference_colors(tolerance: float):
    """The colours of an image-difference heat map as a VTK lookup table: matplotlib's "inferno" from 0 (black) to
    twice ``tolerance`` (pale yellow), in fractions of full scale, larger differences as the top colour."""
    from matplotlib import colormaps

    top = 2.0 * tolerance
    table = vtkLookupTable()
    table.SetNumberOfTableValues(256)
    for index, rgba in enumerate(colormaps["inferno"](np.linspace(0.0, 1.0, 256))):
        table.SetTableValue(index, *rgba[:3], 1.0)
    table.SetRange(0.0, top)
    table.SetAboveRangeColor(*colormaps["inferno"](1.0)[:3], 1.0)
    table.UseAboveRangeColorOn()
    table.Build()
    return table


def difference_bar(tolerance: float):
    """The colour bar of an image-difference heat map: |difference| in fractions of full scale (1 = 255 grey
    levels), 0 to twice ``tolerance``."""
    return legend_bar(difference_colors(tolerance), "difference\n(of full\nscale)", above_range=f"> {2 * tolerance:.3g}")


def default_sample_distance(volume) -> float:
    """Half the smallest voxel spacing (mm): the step both our ray marcher and VTK's mappers use by default."""
    return 0.5 * min(volume.spacing)


def volume_prop(volume, transfer_function, *, mapper: str = "gpu", sample_distance: float | None = None,
                shading: bool | None = None, image=None):
    """A ``vtkVolume`` of ``volume`` drawn by VTK's GPU or CPU (fixed-point) ray caster, placed in the patient.

    ``image`` may pass an already converted ``volume.to_vtk(local=True)`` to share it between views.
    """
    step = sample_distance if sample_distance is not None else default_sample_distance(volume)
    if not step > 0:
        raise ValueError(f"sample distance must be positive (mm), got {step}")
    image = image if image is not None else volume.to_vtk(local=True)
    return vtk_volume_prop(image, transfer_function.to_vtk_property(shading=shading), mapper=mapper,
                           sample_distance=step, user_matrix=vtk_matrix(volume.local_to_world))


def show_background_image(renderer, image: np.ndarray):
    """Show an ``(h, w, 3)`` uint8 frame (row 0 at the top) as ``renderer``'s background; returns the texture.

    This is how our software renderers' frames reach the screen: the camera stays VTK's, so interaction, linking and
    overlays work as for every other view.
    """
    from vtkmodules.vtkRenderingCore import vtkTexture

    height, width = image.shape[:2]
    data = vtkImageData()
    data.SetDimensions(width, height, 1)
    pixels = np.ascontiguousarray(image[::-1, :, :3]).reshape(-1, 3)
    data.GetPointData().SetScalars(numpy_support.numpy_to_vtk(pixels, deep=True))
    texture = vtkTexture()
    texture.SetInputData(data)
    texture.InterpolateOn()
    renderer.SetBackgroundTexture(texture)
    renderer.TexturedBackgroundOn()
    return texture


def clear_background_image(renderer) -> None:
    renderer.TexturedBackgroundOff()
    renderer.SetBackgroundTexture(None)
