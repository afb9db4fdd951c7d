"""A live tactile array on a serial port: an N x M taxel pad read by a microcontroller, the kind a lab builds.

- :mod:`~palpate.hardware.tactile.protocol`: the wire format (a binary frame with sync, counter, counts and a
  CRC, or a CSV line with an XOR checksum), documented in ``docs/tactile_array.md``;
- :mod:`~palpate.hardware.tactile.reader`: the host side: frames read in a thread, lost frames (counter gaps) and
  corrupted ones (bad checksum) counted, never invented, each frame stamped on the host clock from its counter;
- :mod:`~palpate.hardware.tactile.emulator`: the device on a pseudo-terminal, its counts from a model (a press
  motion) or from the simulation (the Dynamixel finger's physics).

``palpate record session --taxels PORT --liberty PORT`` records the array and a Liberty into one file
(:mod:`palpate.hardware.rig`).
"""
