"""What a render mode is: a name, a plain description, typed options, capabilities, and the view content it makes.

A mode turns one item of the scene (a volume, a field, a mesh) into what a view shows. The mode itself holds no
state; :meth:`Mode.create_content` makes a :class:`app.pipeline.content.ViewContent` for one view, and the view
pipeline (:mod:`app.pipeline`) drives it the same way for the command line and for every window view. Adding a mode
therefore means registering one :class:`Mode` object: the command line builds its flags from :attr:`Mode.options`,
the window builds the view's options panel from them, and the mode chooser lists it by :attr:`Mode.group`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

from ..options import HasOptions, Option

if TYPE_CHECKING:  # pragma: no cover
    from ..pipeline.content import ViewContent

#: Item kinds a mode can take as input (see :mod:`app.scene`).
INPUT_KINDS = ("volume", "mesh", "tetmesh")
#: What a mode shows: a surface mesh, a tetrahedral mesh, an image of our software renderers, a VTK volume mapper's
#: picture, or a comparison of two modes.
OUTPUT_KINDS = ("surface", "tetmesh", "image", "volume", "comparison")
#: Groups of the window's mode chooser, in display order.
GROUPS = ("Surfaces", "Volume rendering", "Tetrahedral meshes", "Meshes", "Comparisons")

@dataclass(frozen=True)
class Capabilities:
    """What the pipeline, the command line and the window need to know about a mode beyond its options.

    ``parallel_only``: draws with parallel projection only (a perspective camera is followed in parallel).
    ``preview_stride``: voxel stride of the mode's own coarse path for previews while the isovalue is dragged
    (0: the mode has none and always works at full resolution).
    ``uses_iso``: the picture depends on the isovalue (surfaces). ``uses_transfer_function``: on the transfer
    function (volume rendering). ``accepts_cutaways``: honours cut-away tools.
    ``software``: our own renderer drawing images on the CPU (the view renders previews while the camera moves).
    """

    parallel_only: bool = False
    preview_stride: int = 0
    uses_iso: bool = False
    uses_transfer_function: bool = False
    accepts_cutaways: bool = False
    software: bool = False
    clip_plane: bool = False  # the view cuts the content with a plane the window lets the user drag (issue 16)

    def describe(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class Mode(HasOptions, ABC):
    """A render mode. Subclasses (one per kind of content) implement :meth:`create_content`.

    ``origin`` says whose implementation it is (``"ours"`` or ``"VTK"``); ``group`` places it in the window's chooser.
    """

    name: str
    label: str
    description: str
    group: str
    origin: str
    input: str
    output: str
    options: tuple[Option, ...] = ()
    capabilities: Capabilities = field(default_factory=Capabilities)

    def __post_init__(self) -> None:
        if self.input not in INPUT_KINDS:
            raise ValueError(f"mode {self.name!r}: input must be one of {', '.join(INPUT_KINDS)}")
        if self.output not in OUTPUT_KINDS:
            raise ValueError(f"mode {self.name!r}: output must be one of {', '.join(OUTPUT_KINDS)}")
        if self.group not in GROUPS:
            raise ValueError(f"mode {self.name!r}: group must be one of {', '.join(GROUPS)}")
        names = [option.name for option in self.options]
        if len(set(names)) != len(names):
            raise ValueError(f"mode {self.name!r} declares an option twice")

    def resolve_options(self, values: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Every option of the mode with ``values`` applied over the defaults, validated (a ValueError names an
        option the mode does not take and lists those it has)."""
        return self._resolve(f"mode {self.name!r}", values)

    # -- content --------------------------------------------------------------------------------------------------
    @abstractmethod
    def create_content(self, options: Mapping[str, Any]) -> "ViewContent":
        """The content object one view uses to show this mode (see :mod:`app.pipeline.content`)."""

    def describe(self) -> dict[str, Any]:
        """JSON-ready description (``voxelscope modes --json``)."""
        return {
            "name": self.name, "label": self.label, "description": self.description, "group": self.group,
            "origin": self.origin, "input": self.input, "output": self.output,
            "options": [option.describe() for option in self.options],
            "capabilities": self.capabilities.describe(),
        }
