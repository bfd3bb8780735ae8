"""Comparisons a view can show: one surface coloured by its distance to another, and the difference of two
renderings as a heat map with its numbers. Headless, so the workbench, tests and benchmarks share them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from algorithms._progress import ProgressCallback, scaled

from .meshing import extract_surface
from .modes import SurfaceResult
from .volume import Volume

DISTANCE_ARRAY = "distance_mm"


def surface_distance(volume: Volume, test: str, reference: str, iso: float, *,
                     progress: ProgressCallback = None) -> SurfaceResult:
    """The ``test`` method's surface with a point array ``distance_mm``: each vertex's distance to ``reference``'s.

    ``stats`` carries the test surface's counts plus ``hausdorff_mm`` (largest vertex distance either way),
    ``mean_mm`` (mean symmetric surface distance) and ``p95_mm`` (95th percentile of the test-to-reference
    distances).
    """
    from vtkmodules.util import numpy_support

    from algorithms.surface_compare import distance_to_surface, surface_arrays

    ours = extract_surface(volume, test, iso, progress=scaled(progress, 0.0, 0.3))
    theirs = extract_surface(volume, reference, iso, progress=scaled(progress, 0.3, 0.5))
    points_a, triangles_a = surface_arrays(ours.polydata)
    points_b, triangles_b = surface_arrays(theirs.polydata)
    if len(triangles_a) == 0 or len(triangles_b) == 0:
        raise ValueError(f"no surface at {iso:g} {volume.units_label}: nothing to compare")
    a_to_b = distance_to_surface(points_a, (points_b, triangles_b), progress=scaled(progress, 0.5, 0.8))
    b_to_a = distance_to_surface(points_b[np.unique(triangles_b)], (points_a, triangles_a),
                                 progress=scaled(progress, 0.8, 1.0))
    used = np.unique(triangles_a)
    array = numpy_support.numpy_to_vtk(a_to_b.astype(np.float32), deep=True)
    array.SetName(DISTANCE_ARRAY)
    polydata = ours.polydata.NewInstance()
    polydata.ShallowCopy(ours.polydata)
    polydata.GetPointData().AddArray(array)
    stats = dict(ours.stats)
    stats.update({
        "hausdorff_mm": float(max(a_to_b[used].max(), b_to_a.max())),
        "mean_mm": float((a_to_b[used].sum() + b_to_a.sum()) / (used.size + b_to_a.size)),
        "p95_mm": float(np.percentile(a_to_b[used], 95)),
        "reference_triangles": theirs.stats["triangles"],
    })
    return SurfaceResult(polydata, stats)


@dataclass
class ImageDifference:
    """The heat map of |test - reference| and the comparison numbers (PSNR over the foreground, RMSE, SSIM)."""

    heatmap: np.ndarray  # (h, w, 3) uint8
    numbers: dict[str, Any] = field(default_factory=dict)


def image_difference(test: np.ndarray, reference: np.ndarray, *, background=(0.0, 0.0, 0.0)) -> ImageDifference:
    """Compare two renderings of the same view (``(h, w, 3)`` uint8 or float in [0, 1])."""
    from algorithms.image_metrics import compare_images, difference_heatmap

    comparison = compare_images(test, reference, background=background)
    return ImageDifference(difference_heatmap(test, reference), comparison.as_dict())
