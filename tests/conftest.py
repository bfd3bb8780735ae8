"""Shared fixtures. VTK is configured as the application configures it (STDThread SMP, errors to logging)."""

from __future__ import annotations

import numpy as np
import pytest

from app.vtk_setup import configure_vtk

configure_vtk()


@pytest.fixture(scope="session")
def ct_phantom():
    """The CT head phantom at a reduced size (fast), int16 HU, anisotropic spacing."""
    from app.datasets import ct_head_phantom

    return ct_head_phantom(shape=(40, 96, 96), spacing=(2.5, 2.5, 5.4))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
