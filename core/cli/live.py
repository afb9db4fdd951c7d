"""The ``--live`` options of ``palpate run`` and ``palpate replay``: a Foxglove WebSocket server for the run."""

from __future__ import annotations

import argparse
import sys


def add_live_options(p: argparse.ArgumentParser) -> None:
    """``--live [PORT]`` and ``--live-hold SECONDS`` (run and replay)."""
    g = p.add_argument_group("live view (Foxglove WebSocket; needs pip install 'palpate[live]')")
    g.add_argument("--live", nargs="?", type=int, const=8765, default=None, metavar="PORT",
                   help="serve the recording's channels and the map after every press to Foxglove on "
                   "ws://127.0.0.1:PORT while it runs (default port 8765; 0 picks a free one)")
    g.add_argument("--live-hold", type=float, default=0.0, metavar="SECONDS",
                   help="keep serving the final maps this long after the end (Ctrl-C stops earlier)")


def open_live(args: argparse.Namespace):
    """The live server the options ask for (None without --live); checked before any work starts."""
    if args.live is None:
        return None
    from palpate.core.errors import ValidationError
    from palpate.core.io.live import LiveServer
    from palpate.core.world.resources import models_dir

    if not (0 <= args.live <= 65535):
        raise ValidationError(f"--live: port must be 0..65535, got {args.live}")
    if not (args.live_hold >= 0):
        raise ValidationError(f"--live-hold must be >= 0 s, got {args.live_hold}")
    server = LiveServer(port=args.live)
    # Printed even with --quiet: the address is what a user needs to connect.
    print(f"live view on {server.url} (in Foxglove: Open connection; layout: import "
          f"{models_dir() / 'foxglove_layout.json'})", file=sys.stderr, flush=True)
    return server


def hold_live(server, seconds: float) -> None:
    """Keep serving (the latest maps reach new clients) for ``seconds``, or until Ctrl-C; then stop."""
    import time

    if server is None:
        return
    try:
        if seconds > 0:
            print(f"serving the final maps on {server.url} for {seconds:g} s (Ctrl-C stops)", file=sys.stderr,
                  flush=True)
            time.sleep(seconds)
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
