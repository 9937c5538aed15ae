"""The time series of the export: the tracking error of hil.core.tracking and its envelope."""

from __future__ import annotations

import numpy as np

from hil.replay.controllers import ScenarioCache
from hil.replay.intervals import VELOCITY_ESTIMATE_TOLERANCE, judge_intervals
from tests.views.rrd_store import Exported, column, first


def test_tracking_error_plots_hold_the_reference_until_the_next_one(exported: Exported) -> None:
    run = exported.run
    error = run.tracking_error()
    assert len(error) > 100
    i = len(error) // 2
    t = error.t_ns[i]
    held = run.reference.values[np.searchsorted(run.reference.t_ns, t, side="right") - 1]
    estimate = run.estimate.values[run.estimate.t_ns == t][0, 3:6]
    np.testing.assert_allclose(error.error[i], estimate - held)
    for k, axis in enumerate(("surge", "sway", "yaw_rate")):
        times, values = column(
            exported.store, f"/plots/tracking_error/{axis}/error", "Scalars:scalars"
        )
        assert times.tolist() == error.t_ns.tolist()
        got = np.array([first(v) for v in values], dtype=np.float64)
        np.testing.assert_allclose(got, error.error[:, k], rtol=1e-6, atol=1e-9)


def test_the_envelope_band_is_the_bound_replay_judges_the_error_against(
    exported: Exported,
) -> None:
    run, transient = exported.run, exported.scenario.transient
    error = run.tracking_error()
    decisions = run.decisions
    # Recomputed here from the tables: the decision in force, its class, the bin.
    want = np.full((len(error), 3), np.nan)
    for n, t in enumerate(error.t_ns):
        before = [d for d in decisions if d.t_ns <= t]
        if not before or before[-1].chosen_index < 0:
            continue
        d = before[-1]
        cls = 2 if d.first else (0 if d.chosen_index == d.reference_index else 1)
        b = min(int((t - d.t_ns) / 1e9 // transient.bin_s), transient.n_bins - 1)
        want[n] = transient.envelopes[cls, b] + np.array(VELOCITY_ESTIMATE_TOLERANCE)
    assert np.isfinite(want).sum() > 100
    classes = {2 if d.first else int(d.chosen_index != d.reference_index) for d in decisions}
    assert {0, 2} <= classes or {1, 2} <= classes  # a start and later decisions
    for k, axis in enumerate(("surge", "sway", "yaw_rate")):
        times, values = column(
            exported.store, f"/plots/tracking_error/{axis}/envelope", "Scalars:scalars"
        )
        assert times.tolist() == error.t_ns.tolist()
        got = np.array(values, dtype=np.float64)
        np.testing.assert_allclose(got[:, 0], want[:, k], rtol=1e-6)
        np.testing.assert_allclose(got[:, 1], -want[:, k], rtol=1e-6)
    # The clean run keeps its envelopes: replay's contract check finds no excess.
    intervals = judge_intervals(run, ScenarioCache().get(exported.scenario), exported.scenario, [])
    assert not any(i.envelope_exceeded for i in intervals)
