"""Torque off on every signal a process can catch: a client holding a Dynamixel finger (the palpate command, or a
script using the Python API) is killed with SIGTERM, SIGHUP or SIGINT while a separate process serves the bus; the
servos' torque registers are then read back over the wire, and the command's recording must be a finished file."""

from __future__ import annotations

import queue
import signal
import subprocess
import sys
import threading
import time

import pytest
from child_process import interruptible

from palpate.core.io.mcap_reader import read_recording
from palpate.hardware import exit_signals
from palpate.hardware.dynamixel import control_table as ct

BAUD = 1_000_000
IDS = (1, 2)
SIGNALS = [signal.SIGTERM, signal.SIGHUP, signal.SIGINT]
# Bounds on waiting for a process, not assertions about timing: a healthy run needs a fraction of them.
START_TIMEOUT = 60.0

PALPATE = "import sys; from palpate.core.cli import main; sys.exit(main(sys.argv[1:]))"
API_CLIENT = """
import sys, time
from palpate.hardware.dynamixel.driver import DynamixelFinger
from palpate.hardware.dynamixel.finger import load_finger
# no 'with', no close(); retries: the bus is another process on a machine the test may load heavily
finger = DynamixelFinger(sys.argv[1], 1_000_000, load_finger(sys.argv[2]), retries=10, answer_timeout=1.0).open()
finger.enable_torque()
print("holding", flush=True)
while True:
    time.sleep(0.5)
"""


class Bus:
    """The emulator in its own process, its torque log read line by line."""

    def __init__(self):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "palpate.hardware.dynamixel.emulator", "--ids", ",".join(map(str, IDS)),
             "--log-torque"], stdout=subprocess.PIPE, text=True)
        self.port = self.proc.stdout.readline().strip()
        assert self.port.startswith("/dev/"), self.port
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line.strip())

    def drain(self) -> list[str]:
        out = []
        while not self.lines.empty():
            out.append(self.lines.get())
        return out

    def wait_for(self, line: str) -> list[str]:
        seen = []
        deadline = time.monotonic() + START_TIMEOUT
        while time.monotonic() < deadline:
            try:
                seen.append(self.lines.get(timeout=0.5))
            except queue.Empty:
                continue
            if seen[-1] == line:
                return seen
        raise AssertionError(f"the bus never logged {line!r}; got {seen}")

    def torque(self) -> dict[int, int]:
        """TORQUE_ENABLE of every servo, read over the wire with dynamixel-sdk."""
        import dynamixel_sdk as sdk

        port = sdk.PortHandler(self.port)
        assert port.openPort() and port.setBaudRate(BAUD)
        port.ser.timeout = 0.001  # reads that wait rather than spin (see driver.SERIAL_POLL)
        ph = sdk.PacketHandler(2.0)
        try:
            out = {}
            for sid in IDS:
                for _ in range(5):  # the bus's process may be slow to answer on a loaded machine: ask again
                    value, result, error = ph.read1ByteTxRx(port, sid, ct.TORQUE_ENABLE[0])
                    if result == sdk.COMM_SUCCESS:
                        break
                assert result == sdk.COMM_SUCCESS and error == 0, ph.getTxRxResult(result)
                out[sid] = value
            return out
        finally:
            port.closePort()

    def close(self) -> None:
        self.proc.terminate()
        self.proc.wait(timeout=10)


@pytest.fixture(scope="module")
def bus():
    b = Bus()
    yield b
    b.close()


def _kill_when_holding(bus: Bus, client: subprocess.Popen, sig: int) -> list[str]:
    try:
        log = bus.wait_for(f"torque {IDS[-1]} 1")  # torque is on (enable writes id 1 then id 2)
        time.sleep(0.3)
        client.send_signal(sig)
        client.wait(timeout=START_TIMEOUT)
    finally:
        if client.poll() is None:  # a client left holding the bus would fail every later test on it
            client.kill()
            client.wait()
    time.sleep(0.2)  # the last log lines cross the pipe
    return log + bus.drain()


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_the_record_command_killed_mid_press_leaves_torque_off_and_a_finished_recording(bus, sig, repo_dir,
                                                                                       tmp_path):
    bus.drain()
    out = tmp_path / "rec.mcap"
    # 2 mm/s: the press takes several seconds, so the signal lands while the finger moves down under torque
    client = subprocess.Popen(
        [sys.executable, "-c", PALPATE, "record", "dynamixel", "--port", bus.port, "--finger",
         str(repo_dir / "models" / "fingers" / "planar2.toml"), "--seconds", "120", "--out", str(out),
         "--press", "0.07", "--speed", "0.002", "--retries", "10",
         # the bus is another process on a machine the test may load heavily: wait for its answers
         "--answer-timeout-ms", "1000"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, preexec_fn=interruptible)
    log = _kill_when_holding(bus, client, sig)
    assert client.returncode == (130 if sig == signal.SIGINT else 128 + sig), client.stderr.read()
    assert bus.torque() == {sid: 0 for sid in IDS}
    # switched off after it had been on: every servo's last torque write is a 0
    last_on = max(i for i, line in enumerate(log) if line.endswith(" 1"))
    assert all(f"torque {sid} 0" in log[last_on + 1:] for sid in IDS), log[last_on:]
    rec = read_recording(out)  # finished: no salvage needed
    assert not rec.salvaged and len(rec.joints) > 10
    end = [a for a in rec.annotations if a.kind == "recording_end"]
    assert len(end) == 1 and end[0].data["samples"] == len(rec.joints)
    assert end[0].data["stop_reason"] == ("interrupted" if sig == signal.SIGINT
                                          else f"terminated by {signal.Signals(sig).name}")
    assert not [a for a in rec.annotations if a.kind == "press_end"]  # it was killed during the press


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_a_python_api_client_killed_while_holding_torque_switches_it_off(bus, sig, repo_dir):
    bus.drain()
    client = subprocess.Popen([sys.executable, "-c", API_CLIENT, bus.port,
                               str(repo_dir / "models" / "fingers" / "planar2.toml")],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=interruptible)
    _kill_when_holding(bus, client, sig)
    assert bus.torque() == {sid: 0 for sid in IDS}
    # SIGTERM/SIGHUP end with the shell's code for the signal; SIGINT as an uncaught KeyboardInterrupt does
    assert client.returncode in ((-sig, 128 + sig) if sig == signal.SIGINT else (128 + sig,))


def test_terminated_is_raised_only_while_held_and_the_previous_handler_comes_back():
    before = signal.getsignal(signal.SIGTERM)
    with exit_signals.holding():
        with pytest.raises(exit_signals.Terminated) as info:
            signal.raise_signal(signal.SIGTERM)
        assert info.value.code == 128 + signal.SIGTERM
        assert str(info.value) == "terminated by SIGTERM"
    assert signal.getsignal(signal.SIGTERM) is before
