"""Terminal progress for long stages: a tqdm bar per stage on stderr, silent when asked (``--quiet``, ``--json``).

On a terminal each stage is a live bar; in a log (stderr not a terminal) each stage prints one line when it ends,
so CI logs carry no carriage returns.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import TextIO

from tqdm import tqdm


@dataclass
class Progress:
    """A bar per stage, e.g. ``training Material_2: 45%|#####     | 9/20 [00:03<00:04]``.

    Attributes:
        enabled: print anything at all (``--quiet`` and ``--json`` turn it off).
        stream: where to print (stderr by default, so ``--json`` output on stdout stays clean).
    """

    enabled: bool = True
    stream: TextIO = field(default_factory=lambda: sys.stderr)
    _bar: tqdm | None = field(default=None, init=False, repr=False)
    _stage: str = field(default="", init=False)
    _total: int = field(default=0, init=False)
    _done: int = field(default=0, init=False)
    _t0: float = field(default=0.0, init=False)
    _unit: str = field(default="step", init=False)

    def _live(self) -> bool:
        return self.enabled and bool(getattr(self.stream, "isatty", lambda: False)())

    def start(self, stage: str, total: int, unit: str = "step") -> None:
        """Begin a stage of ``total`` steps (ends the previous stage's bar); ``unit="B"`` counts bytes."""
        self.close()
        self._stage, self._total, self._done, self._t0 = stage, max(int(total), 1), 0, time.perf_counter()
        self._unit = unit
        if self._live():
            self._bar = tqdm(total=self._total, desc=stage, file=self.stream, leave=True, dynamic_ncols=True,
                             unit=unit, unit_scale=unit == "B", unit_divisor=1024, mininterval=0.1)

    def update(self, done: int, note: str = "") -> None:
        """Show ``done`` of the stage's steps finished (``note``: a short status after the bar)."""
        if not self.enabled:
            return
        self._done = min(int(done), self._total)
        if self._bar is not None:
            if note:
                self._bar.set_postfix_str(note, refresh=False)
            self._bar.update(self._done - self._bar.n)
        if self._done >= self._total:
            self._finish(note)

    def _finish(self, note: str) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        elif self.enabled and self._stage:
            elapsed = time.perf_counter() - self._t0
            amount = (f"{self._total / 2**20:.1f} MiB" if self._unit == "B" else f"{self._done}/{self._total}")
            self.stream.write(f"{self._stage}: {amount} in {elapsed:.1f} s {note}".rstrip() + "\n")
            self.stream.flush()
        self._stage = ""

    def close(self) -> None:
        """End the current stage where it stands (a stage cut short by an error leaves no dangling bar)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        self._stage = ""

    def message(self, text: str) -> None:
        """Print a line (not part of a bar; a live bar is redrawn below it)."""
        if not self.enabled:
            return
        if self._bar is not None:
            tqdm.write(text, file=self.stream)
        else:
            self.stream.write(text + "\n")
            self.stream.flush()
