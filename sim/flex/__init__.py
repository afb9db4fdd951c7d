"""The ``flex`` fidelity: MuJoCo's deformable bodies under the tip, with the mesh corrections measured against the
FE reference.

:mod:`.press` runs one press (:func:`.press.run_flex_press`); :mod:`.model` builds the MJCF window, :mod:`.grid`
and :mod:`.element` lay out its mesh, :mod:`.mixing` places laterally varying material on it; :mod:`.calibration`,
:mod:`.plate` and :mod:`.lump` hold the correction tables (read once per run through :mod:`.tables`), and
:mod:`.calibrate` remeasures them.
"""
