"""A render mode defined by the tests, not by Voxelscope: registering it at run time must be enough for it to reach
the command line and the window (the registry is the only extension point)."""

from __future__ import annotations

from app.modes import Capabilities, Option
from app.modes.surfaces import SurfaceMode


def shifted_faces(options, iso, stride):
    """Voxel faces at the isovalue plus the mode's own ``shift`` option (HU)."""
    from algorithms.surfaces.voxel_faces import VoxelFacesFilter

    algorithm = VoxelFacesFilter()
    algorithm.SetThreshold(iso + options["shift"])
    return algorithm


TEST_MODE = SurfaceMode(
    "test-shifted-faces", "Shifted voxel faces", "Voxel faces at the isovalue plus a shift (a mode made by a test)",
    group="Surfaces", origin="ours", input="volume", output="surface", make_filter=shifted_faces,
    flat_shading=True, capabilities=Capabilities(uses_iso=True),
    options=(Option("shift", "float", 0.0, "test mode: added to the isovalue", unit="HU", minimum=-5000,
                    maximum=5000),),
)
