"""Realism: the sources of variability a real press has, applied around the contact mechanics of every fidelity.

- :mod:`~palpate.sim.realism.profile`: the parameters (finger pulp, press, taxels, pose, material) and presets;
  :mod:`~palpate.sim.realism.profile_file`: profile files, found by name;
- :mod:`~palpate.sim.realism.finger`: the compliant pulp in series with the object, the pad's contact patch;
- :mod:`~palpate.sim.realism.material`: viscoelastic relaxation and softening on repeated presses;
- :mod:`~palpate.sim.realism.taxels`: the pad's non-ideal response (gain spread and drift, creep, hysteresis,
  crosstalk, non-linearity);
- :mod:`~palpate.sim.realism.stage`: one press's realism, as :class:`~palpate.sim.source.SimSource` applies it;
- :mod:`~palpate.sim.realism.calibrate`, :mod:`~palpate.sim.realism.moments`, :mod:`~palpate.sim.realism.search`
  and :mod:`~palpate.sim.realism.cli`: ``palpate calibrate realism``, the
  simulation-based fit of a profile to a per-press parameter table.

The contact mechanics (analytic, rigid, flex) are not edited: the finger's pulp turns the bone's trajectory into
the indentation the object sees before the physics runs, and everything else acts on the physics' trace (force,
pressure, pose) or on the sensor streams afterwards. See docs/realism.md.
"""
