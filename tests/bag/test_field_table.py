"""The field table resolves against the message definitions, and refuses what is not fixed."""

from __future__ import annotations

import pytest

from hil.bag import field_table as ft
from hil.bag import typestore as ts
from hil.bag.errors import SchemaError


@pytest.mark.parametrize("layout", list(ft.LAYOUTS.values()), ids=lambda layout: layout.msgtype)
def test_every_layout_resolves(layout: ft.FixedLayout) -> None:
    off = ft.offsets(layout)
    assert len(off.columns) == len(layout.names)
    assert off.stamped == (layout.msgtype in ft.STAMPED_TYPES)
    assert all(0 <= index < off.n_values for index, _ in off.columns + off.constants)


def test_a_variable_size_message_is_no_fixed_layout() -> None:
    decision = ft.FixedLayout(ts.DECISION, ft.POSE.record, (("x_m", "x"),))
    with pytest.raises(SchemaError, match="is not a fixed layout"):
        ft.offsets(decision)


def test_a_path_the_message_lacks_is_refused() -> None:
    wrong = ft.FixedLayout(ft.WRENCH.msgtype, ft.WRENCH.record, (("surge_n", "force.w"),))
    with pytest.raises(SchemaError, match="has no fields"):
        ft.offsets(wrong)
