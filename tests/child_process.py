"""Child processes that a test interrupts with SIGINT (Ctrl-C).

A process started in the background by a non-interactive shell (a CI runner, `cmd &`, nohup) inherits SIGINT as
ignored, and Python then installs no KeyboardInterrupt handler in its children: a test that sends SIGINT would wait
for a child that never hears it. Such a child gets SIGINT's default back before it starts.
"""

from __future__ import annotations

import signal


def interruptible() -> None:
    """``preexec_fn`` for subprocess.Popen: SIGINT's default action, whatever the test runner inherited."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
