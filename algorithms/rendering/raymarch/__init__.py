"""Ray-marched direct volume rendering: emission-absorption, Blinn-Phong or single scattering (sources 001, 002).

- :mod:`.core`: :class:`RaymarchRenderer` (set up once per volume and transfer function, then one frame per
  camera), :func:`raymarch`, :func:`step_for_samples`, :func:`shading_normals`, :data:`LIGHTING_MODELS`.
- :mod:`.kernels`: the numba ray loop (sampling, lighting, empty-space skipping, early termination).
- :mod:`.filter`: :class:`RaymarchFilter`.
"""

from .core import LIGHTING_MODELS, RaymarchRenderer, raymarch, shading_normals, step_for_samples
from .filter import RaymarchFilter

__all__ = ["LIGHTING_MODELS", "RaymarchFilter", "RaymarchRenderer", "raymarch", "shading_normals", "step_for_samples"]
