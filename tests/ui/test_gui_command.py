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


def plane_lines(image: np.ndarray) -> np.ndarray:
    """Pixels of the slice planes' outlines the 3D views draw (3D Slicer's red, green and yellow, unlit)."""
    from app.slices import PLANE_COLORS

    lines = np.zeros(image.shape[:2], bool)
    for color in PLANE_COLORS.values():
        lines |= np.all(np.abs(image.astype(int) - np.round(np.asarray(color) * 255)) <= 30, axis=2)
    return lines


def view_regions(image: np.ndarray) -> list[np.ndarray]:
    """The four 3D views: the black-background regions of the window with the four largest boxes, in reading order
    (the slice planes' outlines drawn across a view's background count as background; the slice views beside the
    3D views are black around their images too, but lower: three share the window's height)."""
    from scipy import ndimage

    black = (image.max(axis=2) < 8) | plane_lines(image)
    labels, count = ndimage.label(black)
    boxes = ndimage.find_objects(labels)
    sizes = np.array([(box[0].stop - box[0].start) * (box[1].stop - box[1].start) for box in boxes])
    largest = np.argsort(sizes)[::-1][:4] + 1
    regions = sorted((boxes[label - 1] for label in largest), key=lambda box: (box[0].start // 50, box[1].start))
    return [image[box] for box in regions]


def assert_four_views_of_one_object(image: np.ndarray) -> None:
    regions = view_regions(image)
    assert len(regions) == 4
    masks = []
    for quadrant in regions:
        # Lit pixels are the rendered head (the views' background is black, the plane outlines are not the head); the
        # CPU ray caster draws a CT's skull dimmer than the others, so "lit" starts well below mid-grey.
        mask = (quadrant.max(axis=2) > 25) & ~plane_lines(quadrant)
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


def test_gui_opens_a_session_and_screenshots_it(tmp_path):
    """``voxelscope gui --session FILE --screenshot``: a session written headless opens with its layout and modes."""
    from app.io import load_volume
    from app.session import model_state, write_session
    from app.workbench import WorkbenchModel

    path = save_volume(small_ct(shape=(40, 96, 96), spacing=(2.0, 2.0, 4.0)), tmp_path / "head.nii.gz")
    model = WorkbenchModel()
    model.set_volume(load_volume(path))
    model.set_layout("1x2")
    model.set_view_mode(0, "flying-edges")
    model.set_view_mode(1, "vtk-cpu")
    session = write_session(tmp_path / "s.voxelscope.json", model_state(model))
    out = tmp_path / "session.png"
    env = dict(os.environ, XDG_CONFIG_HOME=str(tmp_path / "config"))
    process = subprocess.run([sys.executable, "-m", "app.cli", "gui", "--session", str(session), "--screenshot",
                              str(out), "--exit", "--timeout", "300"], capture_output=True, text=True, timeout=420,
                             env=env)
    assert process.returncode == 0, process.stderr
    image = read_png(out)
    assert image.shape[0] > 400 and image.shape[1] > 600
    bad = subprocess.run([sys.executable, "-m", "app.cli", "gui", "--session", str(tmp_path / "none.json"),
                          "--exit"], capture_output=True, text=True, timeout=120, env=env)
    assert bad.returncode == 1 and "no such session file" in bad.stderr and "Traceback" not in bad.stderr
