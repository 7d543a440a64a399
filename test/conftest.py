"""Shared pytest setup: the DDS test harness (isolated domain per graph, reaped children)."""

pytest_plugins = ["erforce_interfaces.testing"]
