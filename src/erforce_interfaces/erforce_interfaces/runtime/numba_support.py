"""numba for the stack's kernels, imported without scipy.

When numba loads its numpy support it checks whether scipy's BLAS is there (``import
scipy.linalg.cython_blas``), only to choose how np.convolve and np.correlate multiply inside a kernel.
That import loads most of scipy in every process that loads kernels, at each start and each respawn
(docs/decisions/0009). The stack's kernels use no BLAS, so numba is imported here with scipy hidden and
takes its own loop for those two. A kernel that does need BLAS (np.dot, np.linalg) still works: numba
imports scipy.linalg when it compiles one. (Hidden too: ``import scipy`` itself, which numba's import
does only to check scipy's version; the requirements pin a scipy far above the 1.0 it asks for.)

    from erforce_interfaces.runtime.numba_support import numba, register_jitable

``compiled_for``: a kernel called every tick with the same argument types can skip the dispatcher's
type matching, which for a kernel of many arguments costs more than the kernel's work.
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


def compiled_for(kernel, *args):
    """The compiled function of the numba dispatcher ``kernel`` for exactly the types of ``args`` (compiled or
    loaded now if needed), callable without the dispatcher's per-call type matching. The caller passes
    arguments of those types only (same dtypes, dimensions, contiguity): nothing checks them per call."""
    types = tuple(kernel.typeof_pyval(a) for a in args)
    compiled = kernel.overloads.get(types)
    if compiled is None:
        kernel.compile(types)
        compiled = kernel.overloads[types]
    return compiled.entry_point


__all__ = ["compiled_for", "numba", "register_jitable"]
