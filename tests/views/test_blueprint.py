"""The Rerun viewer layout."""

from __future__ import annotations

from hil.views.blueprint import blueprint


def test_blueprint_builds_without_a_scenario() -> None:
    assert blueprint(None) is not None
