"""The EKF consistency watch on innovations drawn from known distributions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2  # type: ignore[import-untyped]

from hil.controllers.consistency import (
    NIS_ALPHA,
    ConsistencyLimits,
    ConsistencyWatch,
    nis_bound,
)

LIMITS = ConsistencyLimits(estimation_position_m=0.0034, pose_std_m=0.001)


@pytest.mark.parametrize("n", [50, 100, 400])
def test_the_nis_bound_is_the_chi_square_quantile(n: int) -> None:
    exact = chi2.ppf(1.0 - NIS_ALPHA, 3 * n) / n
    assert nis_bound(n) == pytest.approx(exact, rel=2e-3)


def _feed(watch: ConsistencyWatch, scale: float, n: int, seed: int, gate: float = 16.27) -> int:
    """Feed n poses whose innovations are `scale` times the model's; return poses fed."""
    rng = np.random.default_rng(seed)
    sigma = LIMITS.pose_std_m
    for i in range(n):
        y = scale * rng.standard_normal(3)  # in units of the model's sigma (P small vs R)
        nis = float(y @ y)
        position = sigma * math.hypot(y[0], y[1])
        if watch.pose(i * 10_000_000, nis, position, gated=nis > gate) is not None:
            return i + 1
    return n


def test_a_consistent_filter_never_breaches() -> None:
    # 20,000 poses (200 s at 100 Hz) from exactly the model: no window breaks a limit.
    watch = ConsistencyWatch(LIMITS)
    assert _feed(watch, 1.0, 20_000, seed=3) == 20_000
    assert watch.breach is None
    assert 3.0 < watch.worst_mean_nis < nis_bound(LIMITS.window)


@pytest.mark.parametrize("scale", [1.5, 3.0])
def test_noisier_poses_than_the_model_breach_within_a_window(scale: float) -> None:
    watch = ConsistencyWatch(LIMITS)
    fed = _feed(watch, scale, 1_000, seed=4)
    breach = watch.breach
    assert breach is not None
    assert fed <= LIMITS.window
    assert "NIS" in breach.broken
    assert breach.mean_nis > breach.nis_bound
    assert "mean NIS" in breach.text()
    assert "limit" in breach.text()
    # Reported once: later poses are not judged.
    assert watch.pose(10**12, 1e6, 1.0, gated=True) is None
    assert watch.breach is breach


def test_gated_poses_and_a_far_estimate_each_breach() -> None:
    gated = ConsistencyWatch(LIMITS)
    for i in range(LIMITS.window):  # NIS fine on average, but one pose in 10 refused
        gated.pose(i, 2.0 if i % 10 else 17.0, 0.001, gated=i % 10 == 0)
    assert gated.breach is not None
    assert gated.breach.broken == ("gated poses",)
    assert gated.breach.poses == LIMITS.min_poses  # judged from the first full half window
    far = ConsistencyWatch(LIMITS)
    for i in range(LIMITS.min_poses):  # NIS low (S large) yet every pose 5 mm away
        far.pose(i, 1.0, 0.005, gated=False)
    assert far.breach is not None
    assert far.breach.broken == ("innovation",)
    assert far.breach.innovation_bound_m == pytest.approx(math.sqrt(2 * 0.001**2 + 0.0034**2))


def test_nothing_is_judged_before_min_poses_and_nan_is_skipped() -> None:
    watch = ConsistencyWatch(LIMITS)
    for i in range(LIMITS.min_poses - 1):
        assert watch.pose(i, 100.0, 0.1, gated=True) is None
        assert watch.pose(i, math.nan, math.nan, gated=False) is None  # not judged
    assert watch.pose(99, 100.0, 0.1, gated=True) is not None


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"estimation_position_m": -1.0}, "estimation_position_m"),
        ({"pose_std_m": 0.0}, "pose_std_m"),
        ({"min_poses": 1}, "min_poses"),
        ({"min_poses": 200}, "min_poses"),
        ({"max_gated_fraction": 1.0}, "max_gated_fraction"),
    ],
)
def test_bad_limits_are_refused(kwargs: dict[str, float], match: str) -> None:
    base = {"estimation_position_m": 0.0034, "pose_std_m": 0.001}
    with pytest.raises(ValueError, match=match):
        ConsistencyLimits(**{**base, **kwargs})  # type: ignore[arg-type]
