"""VTK props of a view: surface actors, distance-coloured surfaces with their colour bar, VTK volume mappers, and
our software renderers' frames shown as the renderer's background.

Every view (a window view or the command line's off-screen scene) builds its props here, so a mode looks the same
on screen and in a PNG.
"""

from __future__ import annotations

import numpy as np

from algorithms.common.vtk_bridge import vtk_matrix

SURFACE_MATERIAL = {"ambient": 0.15, "diffuse": 0.8, "specular": 0.2, "specular_power": 20.0}


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


def distance_actor(polydata, local_to_world, array: str, *, top: float | None = None):
    """A surface coloured by a point array of distances (mm): blue at 0, white halfway, red at ``top``
    (default: the 99th percentile). Returns the actor and a ``vtkScalarBarActor`` titled with the units."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
    from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

    if top is None:
        distances = numpy_support.vtk_to_numpy(polydata.GetPointData().GetArray(array))
        top = float(np.percentile(distances, 99)) if distances.size else 1.0
    top = max(top, 1e-6)
    colors = vtkColorTransferFunction()
    colors.AddRGBPoint(0.0, 0.23, 0.30, 0.75)
    colors.AddRGBPoint(0.5 * top, 0.87, 0.87, 0.87)
    colors.AddRGBPoint(top, 0.71, 0.02, 0.15)
    actor = surface_actor(polydata, local_to_world, scalars=array, scalar_range=(0.0, top), lookup_table=colors)
    bar = vtkScalarBarActor()
    bar.SetLookupTable(colors)
    bar.SetTitle("distance (mm)")
    bar.SetNumberOfLabels(3)
    bar.SetWidth(0.08)
    bar.SetHeight(0.5)
    bar.SetPosition(0.9, 0.25)
    return actor, bar


def default_sample_distance(volume) -> float:
    """Half the smallest voxel spacing (mm): the step both our ray marcher and VTK's mappers use by default."""
    return 0.5 * min(volume.spacing)


def volume_prop(volume, transfer_function, *, mapper: str = "gpu", sample_distance: float | None = None,
                shading: bool | None = None, image=None):
    """A ``vtkVolume`` of ``volume`` drawn by VTK's GPU or CPU (fixed-point) ray caster, placed in the patient.

    ``image`` may pass an already converted ``volume.to_vtk(local=True)`` to share it between views.
    """
    from algorithms.references.vtk_volume_mappers import volume_prop as vtk_volume_prop

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
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkImageData
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
