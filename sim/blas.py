"""BLAS on one thread for the FE solves behind the contact laws and flex's mixing correction.

The axisymmetric FE (sim/reference) solves every surface hat at once, so SuperLU's solve calls level-3 BLAS on many
small supernode blocks, which OpenBLAS splits over its threads. On a machine whose cores are busy those threads
wait for a core, and after the call they keep spinning on one while MuJoCo steps; one thread gives the same numbers
at a fraction of the time (docs/results.md, "BLAS threads", has the measurements).
"""

from __future__ import annotations


def one_blas_thread():
    """A context in which BLAS (OpenBLAS, MKL, ...) runs on one thread, its thread count restored on leaving
    (about 1 ms to enter)."""
    # loaded first: a limit reaches only the BLAS libraries loaded when it is set (SuperLU's is scipy's)
    import scipy.sparse.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits  # the sim extra's, as skfem and mujoco are

    return threadpool_limits(limits=1, user_api="blas")
