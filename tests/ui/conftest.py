"""Fixtures for the workbench tests: the real Qt window under the (virtual) X server, with throw-away settings."""

from __future__ import annotations

import pytest

pytest.importorskip("pytestqt")


@pytest.fixture
def settings(tmp_path):
    from qtpy.QtCore import QSettings

    return QSettings(str(tmp_path / "voxelscope.ini"), QSettings.IniFormat)


@pytest.fixture(scope="session")
def small_ct_file(tmp_path_factory):
    """The CT phantom on a coarse grid (fast views), written as NIfTI like a user's file."""
    from app.datasets import ct_head_phantom
    from app.io import save_volume

    path = tmp_path_factory.mktemp("volumes") / "small_ct.nii.gz"
    return save_volume(ct_head_phantom(shape=(54, 128, 128)), path)  # the sample's field of view, 2.2 x 2.2 x 4.9 mm


@pytest.fixture
def make_window(qtbot, settings):
    """Windows made by the test (``make_window(settings=None, show=True, size=(1200, 800))``; ``size=None`` keeps the
    size the window restores), each deleted after the test, C++ side first (:func:`ui.lifetime.delete_now`), as the
    application deletes its window."""
    from ui.lifetime import delete_now
    from ui.main_window import MainWindow

    made = []

    def make(settings_=None, *, show=True, size=(1200, 800)):
        main = MainWindow(settings=settings if settings_ is None else settings_)
        made.append(main)
        if size is not None:
            main.resize(*size)
        if show:
            main.show()
            qtbot.waitExposed(main, timeout=60_000)  # a loaded machine may take longer than the default 5 s
        return main

    yield make
    for main in reversed(made):
        delete_now(main)


@pytest.fixture
def window(make_window):
    return make_window()


def open_and_wait(qtbot, window, path, timeout=120_000):
    """Open a volume and wait until every visible view has drawn its final frame."""
    with qtbot.waitSignal(window.all_views_ready, timeout=timeout):
        window.open_path(path)
    assert window.views_ready()


def wait_ready(qtbot, window, timeout=120_000):
    qtbot.waitUntil(window.views_ready, timeout=timeout)
