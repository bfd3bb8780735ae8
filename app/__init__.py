"""Voxelscope's Qt-free application layer: volume model and I/O, presets, render modes, meshing, command line.

Nothing here imports Qt or ``ui``; the workbench (``ui``) builds on it, and so do the command line and the tests.
"""

__version__ = "0.1.0"
