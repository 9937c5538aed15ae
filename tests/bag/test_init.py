"""Every public name of hil.bag resolves; unknown names fail clearly."""

from __future__ import annotations

import pytest

import hil.bag


def test_public_names_resolve() -> None:
    for name in hil.bag.__all__:
        assert getattr(hil.bag, name) is not None


def test_unknown_name() -> None:
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        _ = hil.bag.Nope
