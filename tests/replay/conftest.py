"""Fixtures shared by the replay tests."""

from __future__ import annotations

import pytest

from hil.replay.controllers import ScenarioCache


@pytest.fixture(scope="session")
def caches() -> ScenarioCache:
    """Controllers shared by every replay test (one synthesis per layout)."""
    return ScenarioCache()
