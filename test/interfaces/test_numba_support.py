"""erforce_interfaces.runtime.numba_support: numba loads its numpy support without scipy (a process start
is ~0.5 s of CPU shorter), and kernels that do use BLAS or the two functions that BLAS check decides
still compute numpy's results. Each case runs in a fresh interpreter: the point is what it imports."""

import subprocess
import sys

FRESH = """
import sys
from erforce_interfaces.runtime.numba_support import numba
import numpy as np
assert "scipy" not in sys.modules, "numba loaded scipy"
import erforce_ball_model.catch_time as ct, erforce_sim.drivetrain  # the stack's kernels load without it
ct.load_kernels()
assert "scipy" not in sys.modules, "a kernel module loaded scipy"

@numba.njit(cache=False)
def convolve(a, b):
    return np.convolve(a, b)

a, b = np.array([1.0, 2.0, 3.0]), np.array([0.0, 1.0, 0.5])
assert np.array_equal(convolve(a, b), [0.0, 1.0, 2.5, 4.0, 1.5]), convolve(a, b)

@numba.njit(cache=False)
def dot(a, b):
    return np.dot(a, b)

assert dot(a, b) == 3.5  # 2 + 1.5: compiled with scipy's BLAS, imported now
assert "scipy.linalg" in sys.modules
print("ok")
"""


def test_kernels_load_without_scipy_linalg_and_blas_kernels_still_compile():
    out = subprocess.run([sys.executable, "-c", FRESH], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-3000:]


def test_compiled_for_calls_the_kernel_for_those_types_and_updates_arrays_in_place():
    import numpy as np

    from erforce_interfaces.runtime.numba_support import compiled_for, numba

    @numba.njit(cache=False)
    def scaled_sum(rows, values, factor, out):
        total = 0.0
        for r in rows:
            out[r] = values[r] * factor
            total += out[r]
        return total

    values, out = np.array([1.0, 2.0, 4.0]), np.zeros(3)
    kernel = compiled_for(scaled_sum, np.zeros(0, dtype=np.int64), values, 1.0, out)
    assert len(scaled_sum.signatures) == 1  # compiled once, for those types
    assert kernel(np.array([0, 2]), values, 0.5, out) == 2.5  # 0.5 + 2.0
    assert out.tolist() == [0.5, 0.0, 2.0]
    assert compiled_for(scaled_sum, np.zeros(0, dtype=np.int64), values, 1.0, out) is kernel  # no second compile
