"""Every public name of hil.replay resolves; unknown names fail clearly."""

from __future__ import annotations

import pytest

import hil.replay


def test_public_names_resolve() -> None:
    for name in hil.replay.__all__:
        assert getattr(hil.replay, name) is not None


def test_unknown_name() -> None:
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        _ = hil.replay.Nope
