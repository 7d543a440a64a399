"""numba for the stack's kernels, imported without scipy.

When numba loads its numpy support it checks whether scipy's BLAS is there (``import
scipy.linalg.cython_blas``), only to choose how np.convolve and np.correlate multiply inside a kernel.
That import loads most of scipy: ~0.5 s of CPU in every process that loads kernels (the plant, the ball
predictor), at each start and each respawn. The stack's kernels use no BLAS, so numba
is imported here with scipy hidden and takes its own loop for those two. A kernel that does need
BLAS (np.dot, np.linalg) still works: numba imports scipy.linalg when it compiles one. (Hidden too:
``import scipy`` itself, ~45 ms of CPU, which numba's import does only to check scipy's version; the
requirements pin a scipy far above the 1.0 it asks for.)

    from erforce_interfaces.numba_support import numba, register_jitable
"""

from __future__ import annotations

import importlib.abc
import sys


class _HideScipy(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "scipy" or name.startswith("scipy."):
            raise ModuleNotFoundError(f"{name} is not imported while numba starts", name=name)
        return None


def _import_numba():
    if "numba.np.arraymath" in sys.modules:  # numba's numpy support is loaded already
        import numba

        return numba
    hide = _HideScipy()
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
