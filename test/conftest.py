"""Shared pytest setup: the DDS test harness (isolated domain per graph, reaped children)."""

import pytest
from hypothesis import settings

# Hypothesis' default 200 ms deadline per example is a timing target; those live in bench/. On a shared 2-core
# machine an example's wall time says nothing about the property it checks.
settings.register_profile("erforce", deadline=None)
settings.load_profile("erforce")

pytest_plugins = ["erforce_interfaces.tools.testing"]


def pytest_collection_modifyitems(items):
    # Tests over real DDS run node processes on a shared 2-core machine, where scheduling can stretch a
    # deadline. They get one rerun; a failure that repeats still fails the suite. Unit tests get none.
    for item in items:
        if item.get_closest_marker("integration") and not item.get_closest_marker("flaky"):
            item.add_marker(pytest.mark.flaky(reruns=1))
