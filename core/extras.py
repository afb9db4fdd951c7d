"""Optional extras: which pip extra brings which module, and the one-line error a missing one gives.

palpate's base install runs the perception stack, maps, recordings and figures; heavier parts are extras
(``pip install 'palpate[sim]'`` etc., see pyproject.toml). Code that needs one calls :func:`require_extra` before
any work starts, or turns an ImportError into :func:`missing_extra`'s error, so a user reads which extra to install
instead of a traceback.
"""

from __future__ import annotations

from importlib.util import find_spec

from palpate.core.errors import PalpateError

#: top-level module -> the extra that installs it
EXTRA_OF_MODULE = {
    "mujoco": "sim", "trimesh": "sim", "threadpoolctl": "sim",
    "serial": "hardware", "dynamixel_sdk": "hardware",
    "pyvista": "viz", "vtk": "viz", "vtkmodules": "viz",
    "ray": "ray",
    "foxglove": "live",
    "sklearn": "learn",
    "gymnasium": "gym",
    "websockets": "test", "pytest": "test", "hypothesis": "test",
}


class MissingExtraError(PalpateError, ImportError):
    """An optional dependency is not installed; the message names the extra to install."""


def _message(what: str, module: str) -> str:
    extra = EXTRA_OF_MODULE.get(module)
    if extra is None:
        return f"{what} needs the Python module {module!r}, which is not installed"
    return f"{what} needs the '{extra}' extra (module {module!r}): install it with pip install 'palpate[{extra}]'"


def missing_extra(exc: ImportError, what: str) -> MissingExtraError:
    """The error to raise for ``exc`` (an ImportError met while loading ``what``), naming the extra."""
    module = (getattr(exc, "name", None) or str(exc)).split(".")[0]
    return MissingExtraError(_message(what, module))


def require_extra(what: str, *modules: str) -> None:
    """MissingExtraError unless every module can be imported (checked without importing them)."""
    for module in modules:
        if find_spec(module) is None:
            raise MissingExtraError(_message(what, module))
