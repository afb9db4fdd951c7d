"""Where a pressing finger's taxel frames come from: a live tactile array read on its serial port (the real pad, or
its emulator backed by the finger's physics), handed to :class:`~palpate.hardware.dynamixel.press.FingerActuator`
as ``streams(t0, t1) -> (frames, truth)`` on the driver's clock."""

from __future__ import annotations

import time
from dataclasses import dataclass

from palpate.core.errors import DeviceError
from palpate.core.world.scene import Scene
from palpate.hardware.tactile.reader import TactileArrayReader

# How long a press waits, s of wall time, for the array's frames of its last instants to come in (USB latency,
# a busy host); a pad still silent by then is reported, not waited for.
SETTLE = 1.0


@dataclass(frozen=True)
class TaxelPort:
    """A tactile array's serial settings (``[actuator]`` keys ``taxels``, ``taxel_format``, ``taxel_rate``,
    ``taxel_baud``): port, "binary" or "csv", frames per second, bit rate."""

    port: str
    fmt: str = "binary"
    rate: float = 50.0
    baud: int = 115200


def open_reader(port: TaxelPort, scene: Scene, clock) -> TactileArrayReader:
    """A started reader for the scene's pad (rows, cols, sensel area) on ``clock`` (the driver's)."""
    tip = scene.fingertip
    return TactileArrayReader(port.port, rows=tip.rows, cols=tip.cols, sensel_area=tip.sensel_area, fmt=port.fmt,
                              baud=port.baud, rate=port.rate, clock=clock, sensor_id="taxels").start()


def reader_streams(reader: TactileArrayReader, truth=None):
    """``streams(t0, t1)`` for FingerActuator: the array's frames over [t0, t1] (clock of the reader), and
    ``truth(t0, t1)`` when a simulation stands behind the pad (None for a real one)."""

    def streams(t0: float, t1: float):
        deadline = time.monotonic() + SETTLE
        while reader.latest() < t1 - reader.period and time.monotonic() < deadline:
            time.sleep(0.002)
        if reader.latest() < t0:
            raise DeviceError(f"the tactile array on {reader.port} sent no frame for the press ({t0:.3f} to "
                              f"{t1:.3f} s): {reader.stats.to_dict()}")
        return reader.between(t0, t1), (truth(t0, t1) if truth is not None else None)

    return streams
