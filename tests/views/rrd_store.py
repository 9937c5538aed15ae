"""An exported run read back with Rerun's own reader, shared by the view tests."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rerun.chunk import LazyStore

from hil.bag.run_data import RunData
from hil.scenarios import Scenario
from hil.views.rerun_style import TIMELINE


@dataclass(frozen=True)
class Exported:
    bag: Path
    run: RunData
    scenario: Scenario
    rrd: Path
    store: LazyStore


def rows(store: LazyStore, entity: str) -> int:
    chunks = store.stream().filter(content=entity, is_static=False).to_chunks()
    return sum(c.num_rows for c in chunks if c.entity_path == entity)


def column(store: LazyStore, entity: str, component: str) -> tuple[np.ndarray, list[object]]:
    """Return (run_time ns, values) of one temporal component, in time order."""
    times: list[int] = []
    values: list[object] = []
    for chunk in store.stream().filter(content=entity, is_static=False).to_chunks():
        batch = chunk.to_record_batch()
        times.extend(batch.column(TIMELINE).cast("int64").to_pylist())
        values.extend(batch.column(component).to_pylist())
    order = np.argsort(times, kind="stable")
    return np.asarray(times)[order], [values[i] for i in order]


def first(row: object) -> object:
    """Return the first instance of a row read back from Rerun (a list)."""
    assert isinstance(row, list)
    return row[0]
