"""numba for the stack's kernels, imported without scipy.linalg.

When numba loads its numpy support it checks whether scipy's BLAS is there (``import
scipy.linalg.cython_blas``), only to choose how np.convolve and np.correlate multiply inside a kernel.
That import loads most of scipy: ~0.5 s of CPU in every process that loads kernels (the plant, the ball
predictor, the catchers), at each start and each respawn. The stack's kernels use no BLAS, so numba
is imported here with scipy.linalg hidden and takes its own loop for those two. A kernel that does need
BLAS (np.dot, np.linalg) still works: numba imports scipy.linalg when it compiles one.

    from erforce_interfaces.numba_support import numba, register_jitable
"""

from __future__ import annotations

import importlib.abc
import sys


class _HideScipyLinalg(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "scipy.linalg" or name.startswith("scipy.linalg."):
            raise ModuleNotFoundError(f"{name} is not imported while numba starts", name=name)
        return None


def _import_numba():
    if "numba.np.arraymath" in sys.modules:  # numba's numpy support is loaded already
        import numba

        return numba
    hide = _HideScipyLinalg()
    sys.meta_path.insert(0, hide)
    try:
        import numba
        import numba.np.arraymath  # the BLAS check (numba would load it with its first kernel)
    finally:
        sys.meta_path.remove(hide)
    return numba


numba = _import_numba()
register_jitable = numba.extending.register_jitable

__all__ = ["numba", "register_jitable"]
