"""BLAS on one thread for the FE solves behind the contact laws and flex's mixing correction.

The axisymmetric FE (sim/reference) solves every surface hat at once, so SuperLU's solve calls level-3 BLAS on many
small supernode blocks, which OpenBLAS splits over its threads. On a machine whose cores are busy those threads
wait for a core, and after the call they keep spinning on one while MuJoCo steps; one thread gives the same numbers
at a fraction of the time (docs/results.md, "Lumps' cost", has the measurements).
"""

from __future__ import annotations


def blas_controller():
    """A threadpoolctl controller of the BLAS libraries loaded now (SuperLU's, scipy's, among them). Finding them
    reads the process's memory map (~2 ms): a caller limiting BLAS on every press keeps one."""
    # loaded first: a limit reaches only the BLAS libraries loaded when the controller looks (SuperLU's is scipy's)
    import scipy.sparse.linalg  # noqa: F401
    from threadpoolctl import ThreadpoolController  # the sim extra's, as skfem and mujoco are

    return ThreadpoolController()


def one_blas_thread(controller=None):
    """A context in which BLAS (OpenBLAS, MKL, ...) runs on one thread, its thread count restored on leaving.

    ``controller``: a :func:`blas_controller` to reuse (entering is then a few microseconds); by default a new one.
    """
    controller = blas_controller() if controller is None else controller
    return controller.limit(limits=1, user_api="blas")
