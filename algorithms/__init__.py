"""Voxelscope's algorithm cores (NumPy/numba) and their thin VTK filter wrappers. No Qt, no application state.

Public names are re-exported from the modules as they are added; see each module's docstring for the method, its
source document in ``../shared/seeds/`` and the original paper.
"""
