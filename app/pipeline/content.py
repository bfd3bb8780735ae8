"""What one view shows for a mode: the content objects the view pipeline drives.

A content object is made by :meth:`app.modes.base.Mode.create_content` for one view and lives as long as that view
shows that mode with those options. The pipeline (:class:`app.pipeline.view.ViewPipeline`) calls it in this order:

1. :meth:`ViewContent.prepare` - the long work (running our VTK filter or VTK's, a comparison), on a worker thread
   in the window or at once on the command line; it must not touch the renderer;
2. :meth:`ViewContent.install` - on the thread that owns the renderer: add or replace props;
3. for contents whose picture is made per camera (:attr:`ViewContent.uses_frames`, our software renderers),
   :meth:`ViewContent.frame_work` for each camera (it may render VTK references at once, on the owner thread, and
   returns the work for a worker) and :meth:`ViewContent.show_frame` with the result;
4. :meth:`ViewContent.react` when a shared input changes (isovalue, transfer function, sample distance): the content
   says whether it must be prepared again, redrawn, or re-framed.

Subclasses live with their modes, one module per mode family in :mod:`app.modes`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

from algorithms.common.camera import Camera

from .props import default_sample_distance, show_background_image

if TYPE_CHECKING:  # pragma: no cover
    from ..modes.base import Mode
    from ..scene import Item

#: What :meth:`ViewContent.react` may answer.
REBUILD, REDRAW, REFRAME, IGNORE = "rebuild", "redraw", "reframe", "ignore"


@dataclass(frozen=True)
class ViewInputs:
    """Everything a view's content is made from besides the mode's own options; immutable, so a job in a worker
    keeps the inputs it started from while the view moves on to new ones (``dataclasses.replace`` makes those).

    ``item`` is the scene item on show (a volume, a field, a mesh...). ``iso`` is in the item's value units,
    ``sample_distance`` in mm (None: half the smallest voxel spacing), ``background`` an RGB triple in [0, 1].
    ``interactive`` is True in a window view (VTK's mappers may then coarsen their sampling while the camera moves);
    off-screen renders keep every setting fixed. ``tools`` are the cut-away tools (:class:`algorithms.fields.
    cutaway_tools.Tool`, LPS mm) evaluated ``cut_evaluation`` (``binary`` or ``distance``); ``tools_moving`` while one
    is dragged (contents take the cheap path and refine when it is False again).
    """

    item: "Item"
    iso: float = 0.0
    transfer_function: Any = None
    sample_distance: float | None = None
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    interactive: bool = False
    tools: tuple = ()
    cut_evaluation: str = "binary"
    tools_moving: bool = False

    @property
    def volume(self):
        """The item's :class:`~app.volume.Volume` (a ValueError for items that have none)."""
        volume = getattr(self.item, "volume", None)
        if volume is None:
            raise ValueError(f"{self.item.name} is a {self.item.kind}, not a volume")
        return volume

    def tool_set(self, *, moving: bool | None = None):
        """The visible tools as a :class:`~algorithms.common.cutaway.ToolSet` in the item's volume frame, or None
        (no tools, or an item without a volume)."""
        if not self.tools or getattr(self.item, "volume", None) is None:
            return None
        from ..cutaways import tool_set_for

        return tool_set_for(self.volume, self.tools, evaluation=self.cut_evaluation,
                            moving=self.tools_moving if moving is None else moving,
                            frame_to_world=self.item.local_to_world)

    def visible_tools(self) -> list:
        return [tool for tool in self.tools if tool.visible]

    def effective_sample_distance(self) -> float:
        return self.sample_distance if self.sample_distance is not None else default_sample_distance(self.volume)


@dataclass
class Frame:
    """One picture made by a software renderer: ``image`` (h, w, 3) uint8, row 0 at the top, and its numbers.

    Contents whose frames are composited by OpenGL (texture slicing drawn by VTK) have no image of their own; they
    give the frame's ``pixels`` (width, height) instead.
    """

    image: np.ndarray | None
    stats: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    pixels: tuple[int, int] | None = None

    @property
    def size(self) -> tuple[int, int]:
        if self.image is None:
            return tuple(self.pixels or (0, 0))
        height, width = self.image.shape[:2]
        return width, height


class ViewContent(ABC):
    """Base of every content. ``stats`` holds the numbers the view's status line and ``render --json`` report."""

    #: True for contents drawn as one image per camera (our software renderers), which the pipeline renders with
    #: previews while the camera moves.
    uses_frames = False

    def __init__(self, mode: "Mode", options: Mapping[str, Any]) -> None:
        self.mode = mode
        self.options = dict(options)
        self.stats: dict[str, Any] = {}
        self.props: list = []

    # -- the content ------------------------------------------------------------------------------------------------
    def prepare(self, inputs: ViewInputs, *, preview: bool = False, progress=None) -> Any:
        """The long work, off the owner thread; returns what :meth:`install` needs. Default: nothing to do."""
        return None

    @abstractmethod
    def install(self, renderer, inputs: ViewInputs, prepared: Any) -> None:
        """Put the props on ``renderer`` (owner thread), replacing this content's earlier props."""

    def remove(self, renderer) -> None:
        """Take this content's props off ``renderer``."""
        for prop in self.props:
            renderer.RemoveViewProp(prop)
        self.props = []

    def _replace_props(self, renderer, props: list) -> None:
        self.remove(renderer)
        for prop in props:
            if prop.IsA("vtkVolume"):
                renderer.AddVolume(prop)
            elif prop.IsA("vtkActor2D") or prop.IsA("vtkScalarBarActor"):
                renderer.AddViewProp(prop)
            else:
                renderer.AddActor(prop)
        self.props = list(props)

    def react(self, change: str, renderer, inputs: ViewInputs) -> str:
        """A shared input changed (``"iso"``, ``"transfer_function"``, ``"sample_distance"``, ``"background"``,
        ``"cutaways"`` - the cut-away tools):
        update props in place when that is cheap and say what else is needed (REBUILD, REDRAW, REFRAME, IGNORE)."""
        return IGNORE

    def status(self) -> str:
        """One line for the view's header."""
        return ""

    def surface(self):
        """The full-resolution surface on show (a :class:`~app.pipeline.lit_surfaces.SurfaceResult`: ``vtkPolyData`` in
        the volume frame and its statistics), or None."""
        return None

    # -- frames (software renderers) --------------------------------------------------------------------------------
    def frame_work(self, renderer, camera: Camera, size: tuple[int, int]) -> Callable[..., Frame]:
        """For :attr:`uses_frames` contents: the work that makes the frame of ``camera`` (world, LPS) at ``size``."""
        raise TypeError(f"{type(self).__name__} draws with VTK, not frame by frame")

    def show_frame(self, renderer, frame: Frame) -> None:
        """Put a finished frame on ``renderer``."""
        show_background_image(renderer, frame.image)

    def close(self) -> None:
        """Release resources that outlive the props (off-screen reference windows...)."""
