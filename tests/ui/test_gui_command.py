"""``voxelscope gui ... --screenshot OUT.png --exit`` as a user runs it, in a separate process on the X server."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.io import save_volume
from app.pipeline import read_png

from ..app.dicom_helpers import small_ct, write_scanner_folder

MODES = "flying-edges,vtk-marching-cubes,vtk-gpu,vtk-cpu"


def run_gui(path, out, *extra):
    env = dict(os.environ, XDG_CONFIG_HOME=str(Path(out).parent / "config"))  # fresh settings, default window
    process = subprocess.run(
        [sys.executable, "-m", "app.cli", "gui", str(path), "--layout", "2x2", "--modes", MODES,
         "--screenshot", str(out), "--exit", "--timeout", "300", *map(str, extra)],
        capture_output=True, text=True, timeout=420, env=env,
    )
    assert process.returncode == 0, process.stderr
    return read_png(out)


def view_regions(image: np.ndarray) -> list[np.ndarray]:
    """The four 3D views: the four largest black-background regions of the window, in reading order."""
    from scipy import ndimage

    black = image.max(axis=2) < 8
    labels, count = ndimage.label(black)
    sizes = ndimage.sum(black, labels, index=np.arange(1, count + 1))
    largest = np.argsort(sizes)[::-1][:4] + 1
    boxes = ndimage.find_objects(labels)
    regions = sorted((boxes[label - 1] for label in largest), key=lambda box: (box[0].start // 50, box[1].start))
    return [image[box] for box in regions]


def assert_four_views_of_one_object(image: np.ndarray) -> None:
    regions = view_regions(image)
    assert len(regions) == 4
    masks = []
    for quadrant in regions:
        # Bright pixels are the rendered head (the views' background is black).
        mask = quadrant.max(axis=2) > 60
        assert mask.mean() > 0.01, "a view shows nothing"
        masks.append(mask)
    # Same object from the same camera: the silhouettes sit in the same place, with the same extent, in every view.
    shape = np.min([m.shape for m in masks], axis=0)
    masks = [m[: shape[0], : shape[1]] for m in masks]
    centres = np.array([np.argwhere(m).mean(axis=0) for m in masks])
    extents = np.array([np.ptp(np.argwhere(m), axis=0) for m in masks])
    assert np.ptp(centres, axis=0).max() < 0.03 * shape.max(), centres
    assert np.ptp(extents, axis=0).max() < 0.06 * shape.max(), extents


@pytest.mark.parametrize("source", ["sample", "nifti", "dicom"])
def test_gui_screenshot_of_four_modes(tmp_path, source):
    if source == "sample":
        path = "sample"
    else:
        volume = small_ct(shape=(40, 96, 96), spacing=(2.0, 2.0, 4.0))
        if source == "nifti":
            path = save_volume(volume, tmp_path / "head.nii.gz")
        else:
            path = tmp_path / "dicom"
            write_scanner_folder(volume, path)
    image = run_gui(path, tmp_path / "out.png")
    assert image.shape[0] > 400 and image.shape[1] > 600
    assert_four_views_of_one_object(image)


def test_gui_reports_a_bad_path_and_exits(tmp_path):
    process = subprocess.run(
        [sys.executable, "-m", "app.cli", "gui", str(tmp_path / "missing.nii"), "--exit", "--timeout", "60"],
        capture_output=True, text=True, timeout=120,
    )
    assert process.returncode == 1
    assert "missing.nii: no such file or folder" in process.stderr and "Traceback" not in process.stderr


def test_gui_without_a_display_says_so(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    process = subprocess.run([sys.executable, "-m", "app.cli", "gui", "sample"], capture_output=True, text=True,
                             timeout=120, env=env)
    assert process.returncode == 1 and "no display" in process.stderr and "Traceback" not in process.stderr
