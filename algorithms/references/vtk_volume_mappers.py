"""VTK's built-in volume renderers, set up as the references of our renderers: GPU and CPU ray casting.

:func:`volume_prop` builds a ``vtkVolume`` with ``vtkGPUVolumeRayCastMapper`` or
``vtkFixedPointVolumeRayCastMapper`` sampling exactly every ``sample_distance`` mm (automatic adjustment off, no
jittering), so a frame of ours and a frame of VTK sample the volume alike and can be compared pixel by pixel.
"""

from __future__ import annotations

from ..common.validation import validated_distance
from ..common.vtk_bridge import vtk_matrix

#: The mappers :func:`volume_prop` builds, by name.
MAPPERS = ("gpu", "cpu")


def volume_prop(image, vtk_volume_property, *, mapper: str = "gpu", sample_distance: float, user_matrix=None):
    """A ``vtkVolume`` of ``image`` rendered by VTK's GPU or CPU (fixed-point) ray caster.

    Parameters
    ----------
    image : vtkImageData
        The volume (point scalars), in the frame the prop is placed from.
    vtk_volume_property : vtkVolumeProperty
        Colour and opacity transfer functions, shading, interpolation.
    mapper : {"gpu", "cpu"}
        ``vtkGPUVolumeRayCastMapper`` (OpenGL; lock to the input spacing off, no jittering) or
        ``vtkFixedPointVolumeRayCastMapper`` (multi-threaded CPU; one ray per pixel, the same sample distance
        while interacting).
    sample_distance : float
        Distance between samples along a ray, mm; automatic adjustment is off for both mappers.
    user_matrix : ndarray (4, 4) or vtkMatrix4x4, optional
        Placement of the image's frame in the scene (e.g. a volume's ``local_to_world``); none by default.

    Returns
    -------
    vtkVolume
        Compositing blend mode.

    Raises
    ------
    ValueError
        For an unknown mapper, a sample distance that is not a positive number, or a user matrix that is not a
        finite 4x4 matrix.
    """
    from vtkmodules.vtkRenderingCore import vtkVolume
    from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper, vtkGPUVolumeRayCastMapper
    import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401 - registers the OpenGL GPU mapper

    sample_distance = validated_distance(sample_distance, "sample_distance")
    if mapper == "gpu":
        vtk_mapper = vtkGPUVolumeRayCastMapper()
        vtk_mapper.SetAutoAdjustSampleDistances(0)
        vtk_mapper.SetLockSampleDistanceToInputSpacing(0)
        vtk_mapper.SetSampleDistance(sample_distance)
        vtk_mapper.SetUseJittering(0)
    elif mapper == "cpu":
        vtk_mapper = vtkFixedPointVolumeRayCastMapper()
        vtk_mapper.SetAutoAdjustSampleDistances(0)
        vtk_mapper.SetSampleDistance(sample_distance)
        vtk_mapper.SetInteractiveSampleDistance(sample_distance)
        vtk_mapper.SetImageSampleDistance(1.0)
    else:
        raise ValueError(f"mapper must be one of {', '.join(MAPPERS)}, got {mapper!r}")
    vtk_mapper.SetInputData(image)
    vtk_mapper.SetBlendModeToComposite()
    prop = vtkVolume()
    prop.SetMapper(vtk_mapper)
    prop.SetProperty(vtk_volume_property)
    if user_matrix is not None:
        prop.SetUserMatrix(user_matrix if hasattr(user_matrix, "GetElement") else vtk_matrix(user_matrix))
    return prop


__all__ = ["MAPPERS", "volume_prop"]
