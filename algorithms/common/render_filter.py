"""The VTK filter shape shared by our software renderers: a ``vtkImageData`` volume in, an RGBA frame out.

:class:`RendererFilter` holds what every such filter needs: the camera, the image size and the transfer table
(setters that call ``Modified()`` only on a real change), ``WHOLE_EXTENT`` in ``RequestInformation``, the checks
on the input, the renderer's set-up kept between updates (rebuilt only when the input, the table or a set-up option
changes, so moving the camera costs one frame), and the conversion of the frame to a VTK image. Problems are
reported as VTK error events (``ValueError`` and ``TypeError`` of the renderer included, never as exceptions
escaping ``RequestData``), so :func:`algorithms.common.vtk_bridge.run_algorithm` raises a ``VTKError`` with the
message. A cancel (``OperationCancelled`` from VTK's abort flag, see :func:`~algorithms.common.vtk_bridge.
progress_for`) does propagate: :func:`~algorithms.common.vtk_bridge.run_algorithm` turns it back into the
caller's own exception.

The volume reaches the renderer as a read-only view of VTK's own memory (no copy: the filter rebuilds the set-up
when the image is modified), so a renderer holds no second copy of the volume. Every renderer jitters its samples
(``SetJitter``, a set-up option) and renders jitter pass ``SetPassIndex(n)`` (a frame option: averaging passes
0 .. n - 1 refines a still image).

A subclass sets :attr:`label`, implements ``_create_renderer(array, spacing, table, progress)`` (reading
``self._jitter``) and lists its set-up options in ``_setup_key()``.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkCommand
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

from .camera import Camera, checked_camera
from .progress import scaled
from .transfer import TransferTable, checked_table
from .validation import validated_image_size
from .vtk_bridge import array_from_image, has_identity_direction, progress_for


class RendererFilter(VTKPythonAlgorithmBase):
    """Base class: input ``vtkImageData`` (point scalars, identity direction), output an RGBA ``vtkImageData``.

    The output is ``width x height x 1`` with 4-component unsigned char point scalars named ``"rgba"``
    (premultiplied colour and opacity, 0-255), rows from the bottom as in every VTK image. The camera is given in
    the input image's coordinates: its origin is honoured by shifting the camera into the renderer's volume frame.
    ``last_stats`` holds the statistics of the last frame.
    """

    label = "RendererFilter"

    def __init__(self) -> None:
        super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1, outputType="vtkImageData")
        self._camera: Camera | None = None
        self._size = (256, 256)
        self._table: TransferTable | None = None
        self._material: tuple[float, float, float, float] | None = None
        self._jitter = False
        self._pass_index = 0
        self._tools = None
        self._renderer = None
        self._renderer_key: tuple | None = None
        self.last_stats: dict[str, float] = {}

    def _set(self, attribute: str, value) -> None:
        """Set an attribute and mark the filter modified, only if the value changes."""
        if getattr(self, attribute) != value:
            setattr(self, attribute, value)
            self.Modified()

    def SetCamera(self, camera: Camera) -> None:  # noqa: N802 - VTK naming
        self._set("_camera", checked_camera(camera))

    def GetCamera(self) -> Camera | None:  # noqa: N802
        return self._camera

    def SetImageSize(self, width: int, height: int) -> None:  # noqa: N802
        self._set("_size", validated_image_size(width, height))

    def GetImageSize(self) -> tuple[int, int]:  # noqa: N802
        return self._size

    def SetTransferTable(self, table: TransferTable) -> None:  # noqa: N802
        checked_table(table)
        if self._table is None or not table.same_as(self._table):
            self._table = table
            self.Modified()

    def GetTransferTable(self) -> TransferTable | None:  # noqa: N802
        return self._table

    def SetMaterial(self, ambient: float, diffuse: float, specular: float, specular_power: float) -> None:  # noqa: N802
        """Blinn-Phong material of shaded renderers (``vtkVolumeProperty``'s terms): ambient, diffuse and specular
        in [0, 1], a positive specular power. A change rebuilds the renderer's set-up."""
        terms = tuple(float(v) for v in (ambient, diffuse, specular, specular_power))
        if not all(0.0 <= v <= 1.0 for v in terms[:3]) or not terms[3] > 0:
            raise ValueError(f"material terms must lie in [0, 1] with a positive specular power, got {terms}")
        self._set("_material", terms)

    def GetMaterial(self) -> tuple[float, float, float, float] | None:  # noqa: N802
        return self._material

    def SetJitter(self, jitter: bool) -> None:  # noqa: N802
        """Offset each ray's (or pixel's) samples by its jitter value; a change rebuilds the renderer's set-up."""
        self._set("_jitter", bool(jitter))

    def GetJitter(self) -> bool:  # noqa: N802
        return self._jitter

    def SetPassIndex(self, pass_index: int) -> None:  # noqa: N802
        """The jitter pass of the next frame (0 for a still frame; see ``algorithms.common.sampling``)."""
        if isinstance(pass_index, bool) or int(pass_index) != pass_index or pass_index < 0:
            raise ValueError(f"the pass index must be a non-negative integer, got {pass_index!r}")
        self._set("_pass_index", int(pass_index))

    def GetPassIndex(self) -> int:  # noqa: N802
        return self._pass_index

    def SetTools(self, tools) -> None:  # noqa: N802
        """Cut-away tools (:class:`algorithms.common.cutaway.ToolSet` in the input image's coordinates, or None):
        a frame option - evaluated per sample, the set-up is kept (moving a tool rewrites nothing)."""
        if tools is not None and len(tools) == 0:
            tools = None
        old = None if self._tools is None else self._tools.key()
        new = None if tools is None else tools.key()
        self._tools = tools
        if old != new:
            self.Modified()

    def GetTools(self):  # noqa: N802
        return self._tools

    def _material_keywords(self) -> dict[str, float]:
        """The material as the renderers' keyword arguments (empty: the renderer's defaults)."""
        if self._material is None:
            return {}
        return dict(zip(("ambient", "diffuse", "specular", "specular_power"), self._material))

    # -- for subclasses ------------------------------------------------------------------------------------
    def _setup_key(self) -> tuple:
        """The set-up options; a change rebuilds the renderer."""
        return ()

    # -- pipeline ---------------------------------------------------------------------------------------------
    def RequestInformation(self, request, in_info, out_info):  # noqa: N802
        width, height = self._size
        out_info.GetInformationObject(0).Set(
            vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT(), (0, width - 1, 0, height - 1, 0, 0), 6
        )
        return 1

    def RequestUpdateExtent(self, request, in_info, out_info):  # noqa: N802
        """The whole volume is needed for any frame (the output's extent is the picture's, not the volume's)."""
        info = in_info[0].GetInformationObject(0)
        info.Set(vtkStreamingDemandDrivenPipeline.UPDATE_EXTENT(),
                 info.Get(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT()), 6)
        return 1

    def _fail(self, problem: str) -> int:
        self.InvokeEvent(vtkCommand.ErrorEvent, problem)
        return 0

    def RequestData(self, request, in_info, out_info):  # noqa: N802
        image = vtkImageData.GetData(in_info[0], 0)
        output = vtkImageData.GetData(out_info, 0)
        if self._camera is None or self._table is None:
            return self._fail(f"{self.label} needs a camera (SetCamera) and a transfer table (SetTransferTable)")
        if not has_identity_direction(image):
            return self._fail(f"{self.label} expects an input image with the identity direction matrix")
        progress = progress_for(self)
        # The C++ address identifies the input (a Python wrapper's id changes from one update to the next).
        key = (image.GetMTime(), image.__this__, id(self._table), image.GetSpacing(), self._jitter,
               self._setup_key())
        try:
            if self._renderer is None or key != self._renderer_key:
                self._renderer = None  # release the old set-up before building the new one
                array = array_from_image(image)
                array.setflags(write=False)  # a view of VTK's memory: the renderer samples it without a copy
                self._renderer = self._create_renderer(array, image.GetSpacing(), self._table,
                                                       scaled(progress, 0.0, 0.5))
                self._renderer_key = key
            shift = np.eye(4)
            shift[:3, 3] = -np.asarray(image.GetOrigin(), dtype=np.float64)
            width, height = self._size
            extra = {} if self._tools is None else {"tools": self._tools.in_frame(np.linalg.inv(shift))}
            result = self._renderer.render(self._camera.transformed(shift), width, height,
                                           pass_index=self._pass_index, progress=scaled(progress, 0.5, 1.0), **extra)
        except (ValueError, TypeError) as exc:
            return self._fail(f"{self.label}: {exc}")
        self.last_stats = dict(result.stats)
        pixels = np.clip(np.rint(result.rgba[::-1] * 255.0), 0, 255).astype(np.uint8)
        scalars = numpy_support.numpy_to_vtk(pixels.reshape(-1, 4), deep=True)
        scalars.SetName("rgba")
        output.SetDimensions(width, height, 1)
        output.SetOrigin(0.0, 0.0, 0.0)
        output.SetSpacing(1.0, 1.0, 1.0)
        output.GetPointData().SetScalars(scalars)
        return 1
