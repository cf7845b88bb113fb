"""Test settings: hypothesis derandomised so that CI runs are repeatable (same examples every run)."""

from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, deadline=None)
settings.load_profile("repeatable")
