"""Synthetic volumes for tests, benchmarks and the sample data, as the application uses them.

The generators live in :mod:`algorithms.datasets` (so tests of the algorithms need no application) and are
re-exported here; :func:`ct_head_phantom` wraps the FORBILD head phantom's array (:mod:`algorithms.datasets.forbild`)
in an :class:`app.volume.Volume` with its geometry, units (HU) and modality (CT): the bundled sample is
``ct_head_phantom()`` saved as NIfTI (``python -m app.samples`` regenerates it bit for bit). :func:`egg_head_phantom`
is the simpler synthetic head the project used before (an egg-shaped skull on a neck), kept for the tests that need
its particular anatomy.

Families (see :mod:`algorithms.datasets.volumes`): source 000 (Dutch BSc thesis on voxel models as triangle
strips, see docs/references.md), section 8.2: :func:`worst_case`, :func:`spheres`, :func:`pillars`,
:func:`scatter`; source 004 (Tavira Rodríguez de Liébana, *Optimización del renderizado de volumen mediante la
técnica shear-warping*, 2017), section 6.1: :func:`random_volume`; analytic fields :func:`sphere_field`,
:func:`ellipsoid_field`, :func:`torus_field`.
"""

from __future__ import annotations

import numpy as np

from algorithms.datasets.forbild import SAMPLE_SHAPE, SAMPLE_SPACING, forbild_head_array, grid_origin
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
    "egg_head_phantom",
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
    shape=SAMPLE_SHAPE,
    spacing=None,
    *,
    noise_hu: float = 0.0,
    seed: int = 0,
    scalp: bool = True,
    table: bool = True,
    progress=None,
) -> Volume:
    """The FORBILD head phantom on a CT grid in Hounsfield units, as a :class:`~app.volume.Volume` (int16, LPS, CT).

    The values are :func:`algorithms.datasets.forbild.forbild_head_array` (see there for the anatomy, the sampling
    and the parameters); the geometry is that of an axial series with identity direction, the head centred on the
    LPS origin and the grid centred 14 mm behind it (the table lies behind the head). The default grid is the
    sample's: 512 x 512 pixels of 0.546875 mm and 176 slices of 1.5 mm. Without ``spacing`` a grid of another
    ``shape`` covers the sample's field of view (280 x 280 x 264 mm: the whole head, the head rest and the table).
    """
    shape = tuple(int(v) for v in shape)
    if spacing is None:
        spacing = tuple(n0 * s0 / n for n, n0, s0 in zip(shape[::-1], SAMPLE_SHAPE[::-1], SAMPLE_SPACING))
    spacing = tuple(float(v) for v in spacing)
    values = forbild_head_array(shape, spacing, noise_hu=noise_hu, seed=seed, scalp=scalp, table=table,
                                progress=progress)
    return Volume(
        values,
        spacing=spacing,
        origin=grid_origin(shape, spacing),
        direction=np.eye(3),
        modality="CT",
        units="HU",
        metadata={"source_format": "synthetic", "description": "FORBILD head phantom (Voxelscope)", "seed": seed,
                  "noise_hu": noise_hu},
    )


def egg_head_phantom(
    shape=(108, 256, 256),
    spacing=(0.9375, 0.9375, 2.0),
    *,
    noise_hu: float = 0.0,
    seed: int = 0,
) -> Volume:
    """The project's earlier synthetic head (egg-shaped skull on a neck), as a :class:`~app.volume.Volume` (int16 HU).

    The values are :func:`algorithms.datasets.volumes.ct_head_array` (see there for its anatomy); the geometry is an
    axial series centred on the origin, identity direction. Tests that need its particular anatomy (a neck, an
    airway, a closed skull base) use it; everything that stands for a CT uses :func:`ct_head_phantom`.
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
        metadata={"source_format": "synthetic", "description": "Voxelscope egg head phantom", "seed": seed,
                  "noise_hu": noise_hu},
    )
