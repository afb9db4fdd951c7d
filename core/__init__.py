"""palpate perception stack: stream types, features, fits, haptic memory, maps, run loop.

numpy/scipy only; never imports palpate.sim or palpate.hardware.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("palpate")
except PackageNotFoundError:  # running from a source tree without install
    __version__ = "0+unknown"
