"""The time series of the export: the tracking error is the one of hil.core.tracking."""

from __future__ import annotations

import numpy as np

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
