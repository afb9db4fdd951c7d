"""Putting streams from separate devices on one clock and into one workspace frame.

A tactile pad and a pose tracker recorded by two programs (two computers, two clocks) give two files whose times
differ by an unknown offset and drift, and whose positions are in the tracker's frame, not the map grid's.

- ``events``: press events in each stream (c_P contacts; reversals of the fingertip's motion).
- ``clock``: the clock map between them, estimated from the presses with its uncertainty, or given.
- ``calibration``: the tracker frame placed on the workspace grid (touch points, or a given transform).
- ``merge``: one stream on the taxel clock and in the grid frame, ready for the perception stack.

Device file formats stay in ``palpate.hardware``; everything here works on TaxelFrame / PoseSample streams.
"""
