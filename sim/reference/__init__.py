"""The independent reference for the contact mechanics: a converged axisymmetric finite-element solution of a rigid
sphere pressed into an elastic sample (layers, an on-axis inclusion, finite width) on a rigid base.

numpy, scipy and scikit-fem only (no MuJoCo): :mod:`.sample` describes the sample, :mod:`.mesh` grades the mesh,
:mod:`.fe` solves the frictionless contact, :mod:`.bonded_layer` holds the published thin-layer correction it is
checked against, :mod:`.tables` caches its results as data under models/. benchmarks/fe_reference.py shows its
mesh convergence and how far the closed-form rungs are from it.
"""
