"""Synthetic volumes for tests, benchmarks and the sample data, as the application uses them.

The generators live in :mod:`algorithms.datasets.volumes` (so tests of the algorithms need no application) and
are re-exported here; :func:`ct_head_phantom` wraps the phantom's array in an :class:`app.volume.Volume` with its
geometry, units (HU) and modality (CT). The bundled sample ``sample_volumes/ct_head_phantom.nii.gz`` is
``ct_head_phantom()`` saved as NIfTI (``python -m app.samples`` regenerates it bit for bit).

Families (see :mod:`algorithms.datasets.volumes`): source 000 (Dutch BSc thesis on voxel models as triangle
strips, see docs/references.md), section 8.2: :func:`worst_case`, :func:`spheres`, :func:`pillars`,
:func:`scatter`; source 004 (Tavira Rodríguez de Liébana, *Optimización del renderizado de volumen mediante la
técnica shear-warping*, 2017), section 6.1: :func:`random_volume`; analytic fields :func:`sphere_field`,
:func:`ellipsoid_field`, :func:`torus_field`.
"""

from __future__ import annotations

import numpy as np

from algorithms.datasets.volumes import (
    FAMILIES,
    centred_origin,
    ct_head_array,
    ellipsoid_field,
    family,
    pillars,
    random_volume,
    scatter,
    sphere_field,
    spheres,
    torus_field,
    worst_case,
)

from .volume import Volume

__all__ = [
    "FAMILIES",
    "ct_head_phantom",
    "ellipsoid_field",
    "family",
    "pillars",
    "random_volume",
    "scatter",
    "sphere_field",
    "spheres",
    "torus_field",
    "worst_case",
]


def ct_head_phantom(
    shape=(108, 256, 256),
    spacing=(0.9375, 0.9375, 2.0),
    *,
    noise_hu: float = 0.0,
    seed: int = 0,
) -> Volume:
    """A synthetic CT of a head in Hounsfield units, as a :class:`~app.volume.Volume` (int16, LPS, modality CT).

    The values are :func:`algorithms.datasets.volumes.ct_head_array` (see there for the parameters and the
    anatomy); the geometry is that of an axial series centred on the origin, identity direction.
    """
    values = ct_head_array(shape, spacing, noise_hu=noise_hu, seed=seed)
    spacing = tuple(float(v) for v in spacing)
    return Volume(
        values,
        spacing=spacing,
        origin=centred_origin(values.shape, spacing),
        direction=np.eye(3),
        modality="CT",
        units="HU",
        metadata={"source_format": "synthetic", "description": "Voxelscope CT head phantom", "seed": seed,
                  "noise_hu": noise_hu},
    )
