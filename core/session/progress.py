"""Terminal progress for long runs: one bar per stage on stderr, silent when asked or when not a terminal."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import TextIO


@dataclass
class Progress:
    """A bar per stage, e.g. ``training Material_2  [#########-----------]  9/20  3.1 s``.

    Attributes:
        enabled: print anything at all (``--quiet`` turns it off).
        stream: where to print (stderr by default, so ``--json`` output on stdout stays clean).
        width: bar width in characters.
    """

    enabled: bool = True
    stream: TextIO = field(default_factory=lambda: sys.stderr)
    width: int = 24
    _stage: str = field(default="", init=False)
    _total: int = field(default=0, init=False)
    _t0: float = field(default=0.0, init=False)

    def start(self, stage: str, total: int) -> None:
        """Begin a stage of ``total`` steps."""
        self._stage, self._total, self._t0 = stage, max(int(total), 1), time.perf_counter()
        self.update(0)

    def update(self, done: int, note: str = "") -> None:
        """Show ``done`` of the stage's steps finished."""
        if not self.enabled:
            return
        filled = int(self.width * min(done, self._total) / self._total)
        bar = "#" * filled + "-" * (self.width - filled)
        line = f"{self._stage:<28} [{bar}] {done:>3}/{self._total:<3} {time.perf_counter() - self._t0:6.1f} s {note}"
        end = "\n" if done >= self._total else ""
        if self.stream.isatty():
            self.stream.write("\r" + line + end)
        elif done >= self._total:  # in logs, one line per finished stage
            self.stream.write(line + "\n")
        self.stream.flush()

    def message(self, text: str) -> None:
        """Print a line (not part of a bar)."""
        if self.enabled:
            self.stream.write(text + "\n")
            self.stream.flush()
