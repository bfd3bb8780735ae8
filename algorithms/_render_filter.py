"""The VTK filter shape shared by our software renderers: a ``vtkImageData`` volume in, an RGBA frame out.

:class:`RendererFilter` holds what every such filter needs: the camera, the image size and the transfer table
(setters that call ``Modified()`` only on a real change), ``WHOLE_EXTENT`` in ``RequestInformation``, the checks
on the input, the renderer's set-up kept between updates (rebuilt only when the input, the table or a set-up option
changes, so moving the camera costs one frame), and the conversion of the frame to a VTK image. Problems are
reported as VTK error events, so :func:`algorithms._vtk.run_algorithm` raises a ``VTKError`` with the message.

A subclass sets :attr:`label`, implements ``_create_renderer(array, spacing, table, progress)`` and lists its
set-up options in ``_setup_key()``.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkCommand
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

from ._progress import scaled
from ._vtk import array_from_image, progress_for
from .camera import Camera
from .transfer import TransferTable


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
        self._renderer = None
        self._renderer_key: tuple | None = None
        self.last_stats: dict[str, float] = {}

    def _set(self, attribute: str, value) -> None:
        """Set an attribute and mark the filter modified, only if the value changes."""
        if getattr(self, attribute) != value:
            setattr(self, attribute, value)
            self.Modified()

    def SetCamera(self, camera: Camera) -> None:  # noqa: N802 - VTK naming
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be an algorithms.camera.Camera, got {type(camera).__name__}")
        self._set("_camera", camera)

    def GetCamera(self) -> Camera | None:  # noqa: N802
        return self._camera

    def SetImageSize(self, width: int, height: int) -> None:  # noqa: N802
        if isinstance(width, bool) or isinstance(height, bool) or int(width) != width or int(height) != height:
            raise ValueError(f"image size must be whole pixels, got {width} x {height}")
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        self._set("_size", (int(width), int(height)))

    def GetImageSize(self) -> tuple[int, int]:  # noqa: N802
        return self._size

    def SetTransferTable(self, table: TransferTable) -> None:  # noqa: N802
        if not isinstance(table, TransferTable):
            raise TypeError(f"table must be an algorithms.transfer.TransferTable, got {type(table).__name__}")
        if self._table is None or not table.same_as(self._table):
            self._table = table
            self.Modified()

    def GetTransferTable(self) -> TransferTable | None:  # noqa: N802
        return self._table

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

    def _fail(self, problem: str) -> int:
        self.InvokeEvent(vtkCommand.ErrorEvent, problem)
        return 0

    def RequestData(self, request, in_info, out_info):  # noqa: N802
        image = vtkImageData.GetData(in_info[0], 0)
        output = vtkImageData.GetData(out_info, 0)
        if self._camera is None or self._table is None:
            return self._fail(f"{self.label} needs a camera (SetCamera) and a transfer table (SetTransferTable)")
        direction = np.array([image.GetDirectionMatrix().GetElement(r, c) for r in range(3) for c in range(3)])
        if not np.allclose(direction, np.eye(3).ravel()):
            return self._fail(f"{self.label} expects an input image with the identity direction matrix")
        progress = progress_for(self)
        key = (image.GetMTime(), id(image), id(self._table), image.GetSpacing(), self._setup_key())
        try:
            if self._renderer is None or key != self._renderer_key:
                self._renderer = self._create_renderer(array_from_image(image), image.GetSpacing(), self._table,
                                                       scaled(progress, 0.0, 0.5))
                self._renderer_key = key
            shift = np.eye(4)
            shift[:3, 3] = -np.asarray(image.GetOrigin(), dtype=np.float64)
            width, height = self._size
            result = self._renderer.render(self._camera.transformed(shift), width, height,
                                           progress=scaled(progress, 0.5, 1.0))
        except ValueError as exc:
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
