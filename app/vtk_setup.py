"""Process-wide VTK settings, applied once by the command line, the workbench and the tests.

- VTK's SMP back end: the PyPI wheels run SMP-parallel filters (vtkFlyingEdges3D, ...) sequentially unless the
  STDThread back end is selected; Voxelscope selects it so VTK's built-ins use every core, as ours do.
- VTK's error and warning output goes to Python's ``logging`` (logger ``vtk``) instead of the terminal, so users
  see our messages, not VTK's; :func:`algorithms.common.vtk_bridge.run_algorithm` turns errors into exceptions.
"""

from __future__ import annotations

import logging

_configured = False
logger = logging.getLogger("vtk")


def smp_backend() -> str:
    from vtkmodules.vtkCommonCore import vtkSMPTools

    return vtkSMPTools.GetBackend()


def set_smp_backend(name: str) -> str:
    """Select VTK's SMP back end ("STDThread" or "Sequential"); returns the back end now in use."""
    from vtkmodules.vtkCommonCore import vtkSMPTools

    vtkSMPTools.SetBackend(name)
    return vtkSMPTools.GetBackend()


def configure_vtk(*, threads: bool = True) -> None:
    """Apply Voxelscope's VTK settings (idempotent)."""
    global _configured
    set_smp_backend("STDThread" if threads else "Sequential")
    if _configured:
        return
    from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow

    class _LoggingOutputWindow(vtkOutputWindow):
        def DisplayText(self, text):  # noqa: N802 - VTK override
            logger.info(text.strip())

        def DisplayErrorText(self, text):  # noqa: N802
            logger.debug(text.strip())  # errors surface as exceptions from run_algorithm

        def DisplayWarningText(self, text):  # noqa: N802
            logger.debug(text.strip())

        def DisplayGenericWarningText(self, text):  # noqa: N802
            logger.debug(text.strip())

    window = _LoggingOutputWindow()
    vtkOutputWindow.SetInstance(window)
    _configure_vtk_window = window  # keep a reference alive for the process
    globals()["_window"] = _configure_vtk_window
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    _configured = True
