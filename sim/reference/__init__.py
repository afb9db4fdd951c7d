"""The independent reference for the contact mechanics: a converged axisymmetric finite-element solution of a rigid
sphere pressed into an elastic sample (layers, an on-axis inclusion, finite width) on a rigid base.

numpy, scipy and scikit-fem only (no MuJoCo): :mod:`.sample` describes the sample, :mod:`.mesh` grades the mesh,
:mod:`.fe` solves the frictionless contact, :mod:`.bonded_layer` holds the published thin-layer correction it is
checked against; its answers for the validity samples are cached as data under models/
(:mod:`palpate.sim.validity.reference`). benchmarks/fe_reference.py shows its mesh convergence and how far plain
Hertz is from it. :mod:`.fe3d` is a 3-D FE of a box block with a box lump, the check of the contact law off the press
axis (benchmarks/fe_offaxis.py).
"""
