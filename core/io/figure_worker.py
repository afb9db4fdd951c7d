"""The entry points of a background figure process (see :mod:`palpate.core.session.figure_jobs`): kept apart so
the process imports matplotlib and the figure code only, not the run's modules."""

from __future__ import annotations

import signal
from collections.abc import Callable
from pathlib import Path

from palpate.core.io import figures


def start(preload: tuple[str, ...] = ()) -> None:
    """Process initialiser: Ctrl-C is the run's to handle (it stops the drawer); pay matplotlib's import and
    font loading now, while the run still trains, and import ``preload`` (e.g. pyvista for a 3-D render) if
    installed."""
    import importlib

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    figures.warm_up()
    for module in preload:
        try:
            importlib.import_module(module)
        except ImportError:
            pass  # the figure that needs it says so when it is drawn


def draw(draw: Callable, path: Path, args: tuple):
    """Draw one figure: ``draw(path, *args)``."""
    return draw(path, *args)
