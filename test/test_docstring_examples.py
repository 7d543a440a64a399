"""The runnable examples in the core modules' docstrings run and print what they show.

Imported by package name (not by file path): numba caches its kernels per module name.
"""

import doctest
import importlib

import pytest

MODULES = (
    "erforce_ball_model.ball_model",
    "erforce_ball_model.catch_time",
    "erforce_ball_model.chip_model",
    "erforce_ball_model.chip_tracking",
    "erforce_ball_model.predictor",
    "erforce_motion.kinematics",
    "erforce_motion.motor_board",
)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} shows no example"
    assert result.failed == 0
