"""The transient budget: validation, the horizon, bin look-ups, hashing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.transient import (
    LATE_S,
    N_CLASSES,
    BudgetClass,
    TransientBudget,
    TransientBudgetError,
    horizon_bins,
)

FloatArray = np.ndarray


def random_budget(seed: int, n_bins: int = 9, bin_s: float = 0.25) -> TransientBudget:
    rng = np.random.default_rng(seed)
    env = rng.uniform(0.0, 0.1, size=(3, n_bins, 3))
    position = np.cumsum(rng.uniform(0.0, 0.02, size=(3, n_bins)), axis=1)
    heading = np.cumsum(rng.uniform(0.0, 0.03, size=(3, n_bins)), axis=1)
    return TransientBudget(bin_s, env, position, heading, 0.002, 0.001, "test")


def test_classes_and_horizon() -> None:
    assert [int(c) for c in BudgetClass] == [0, 1, 2]
    assert [c.name for c in BudgetClass] == ["HOLD", "CHANGE", "START"]
    assert N_CLASSES == 3
    assert pytest.approx(0.1) == LATE_S
    assert horizon_bins(2.0, 0.25) == 9  # 2.1 s: eight bins reach 2.0 only
    assert horizon_bins(2.0, 0.5) == 5
    assert horizon_bins(1.9, 0.5) == 4  # 2.0 s exactly: no extra bin for rounding
    with pytest.raises(TransientBudgetError, match="bin_s > 0"):
        horizon_bins(2.0, 0.0)


def test_zero_covers_the_period_held_late() -> None:
    z = TransientBudget.zero(2.0)
    assert z.n_bins == 9
    assert z.n_classes == 3
    assert z.bin_s == pytest.approx(0.25)
    assert z.horizon_s() == pytest.approx(2.25)
    assert z.envelopes.shape == (3, 9, 3)
    assert z.position_m.shape == z.heading_rad.shape == (3, 9)
    assert z.is_zero()
    t = np.linspace(0.0, 2.1, 8)
    np.testing.assert_array_equal(z.heading_bound_rad(BudgetClass.START, t), 0.0)
    np.testing.assert_array_equal(z.position_bound_m(1, np.array([0.0, 0.2]), t), 0.0)
    assert TransientBudget.zero(2.0, 12).n_bins == 12
    with pytest.raises(TransientBudgetError, match=r"n_bins=8 .* do not cover .* \(need 9\)"):
        TransientBudget.zero(2.0, 8)
    with pytest.raises(TransientBudgetError, match="tau_s > 0"):
        TransientBudget.zero(0.0)


def test_bounds_look_up_the_bin_that_ends_at_or_after_t() -> None:
    b = random_budget(0)
    # Bin j covers (j bin_s, (j + 1) bin_s]; t = 0 is in bin 0, a bin's end is in that bin.
    t = np.array([0.0, 0.1, 0.25, 0.2500001, 1.0, 1.9, 2.0, 2.05, 2.1, 2.25])
    want = np.array([0, 0, 0, 1, 3, 7, 7, 8, 8, 8])
    np.testing.assert_array_equal(b.bin_index(t), want)
    for cls in BudgetClass:
        np.testing.assert_array_equal(b.heading_bound_rad(cls, t), b.heading_rad[cls, want])
        speeds = np.array([0.0, 0.1, 0.2236])
        rho = b.position_bound_m(cls, speeds, t)
        assert rho.shape == (3, t.size)
        # Measured on every input: the same bound for every speed.
        np.testing.assert_array_equal(rho, np.tile(b.position_m[cls, want], (3, 1)))
    assert b.position_bound_m(0, np.zeros(0), t).shape == (0, t.size)


def test_bounds_never_shrink_with_time() -> None:
    b = random_budget(5)
    t = np.linspace(0.0, b.horizon_s(), 101)
    for cls in range(3):
        assert np.all(np.diff(b.heading_bound_rad(cls, t)) >= 0.0)
        assert np.all(np.diff(b.position_bound_m(cls, np.array([0.1]), t)[0]) >= 0.0)


def test_asking_past_the_horizon_is_refused() -> None:
    b = random_budget(1)
    assert b.horizon_s() == pytest.approx(2.25)
    b.heading_bound_rad(0, np.array([2.25]))  # the horizon itself is answered
    with pytest.raises(TransientBudgetError, match=r"t_s = 2.3 s is past the budget's horizon"):
        b.heading_bound_rad(0, np.array([1.0, 2.3]))
    with pytest.raises(TransientBudgetError, match=r"past the budget's horizon 9 x 0\.25"):
        b.position_bound_m(2, np.array([0.1]), np.array([3.0]))


def test_tables_are_copied_and_read_only() -> None:
    env = np.zeros((3, 9, 3))
    pos = np.zeros((3, 9))
    b = TransientBudget(0.25, env, pos, pos, 0.0, 0.0)
    env[0, 0, 0] = 1.0
    pos[0, 0] = 1.0
    assert b.envelopes[0, 0, 0] == 0.0
    assert b.position_m[0, 0] == 0.0
    assert b.heading_rad[0, 0] == 0.0
    for arr in (b.envelopes, b.position_m, b.heading_rad):
        with pytest.raises(ValueError, match="read-only"):
            arr[(0,) * arr.ndim] = 1.0


def test_equality_and_digest_follow_the_numbers() -> None:
    a = random_budget(1)

    def copy(**changes: object) -> TransientBudget:
        args: dict[str, object] = {
            "bin_s": a.bin_s,
            "envelopes": a.envelopes.copy(),
            "position_m": a.position_m.copy(),
            "heading_rad": a.heading_rad.copy(),
            "estimation_position_m": 0.002,
            "estimation_heading_rad": 0.001,
            "source": "test",
        }
        args.update(changes)
        return TransientBudget(**args)  # type: ignore[arg-type]

    same = copy()
    assert a == same
    assert hash(a) == hash(same)
    assert a.digest() == same.digest()
    assert len(a.digest()) == 16
    assert a.digest() in repr(a)
    assert a.digest() == copy(source="x").digest()
    assert a != copy(source="x")
    env = a.envelopes.copy()
    env[2, 8, 2] += 1e-4
    pos = a.position_m.copy()
    pos[1, 8] += 1e-4
    head = a.heading_rad.copy()
    head[2, 8] += 1e-4
    for other in (
        copy(envelopes=env),
        copy(position_m=pos),
        copy(heading_rad=head),
        copy(estimation_position_m=0.003),
        copy(estimation_heading_rad=0.002),
        copy(bin_s=0.3),
    ):
        assert a != other
        assert a.digest() != other.digest()


def _args(**changes: object) -> dict[str, object]:
    args: dict[str, object] = {
        "bin_s": 0.25,
        "envelopes": np.zeros((3, 9, 3)),
        "position_m": np.zeros((3, 9)),
        "heading_rad": np.zeros((3, 9)),
        "estimation_position_m": 0.0,
        "estimation_heading_rad": 0.0,
    }
    args.update(changes)
    return args


_DROP = np.zeros((3, 9))
_DROP[1, :4] = 0.01  # change: 0.01 then 0 from bin 3 to 4


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"bin_s": 0.0}, "bin_s must be > 0"),
        ({"bin_s": math.nan}, "bin_s must be finite"),
        ({"bin_s": "0.25"}, "bin_s must be a number"),
        ({"envelopes": np.zeros((3, 9))}, r"envelopes must have shape \(3, n_bins >= 1, 3\)"),
        ({"envelopes": np.zeros((2, 9, 3))}, "envelopes must have shape"),
        ({"envelopes": np.zeros((3, 0, 3))}, "envelopes must have shape"),
        ({"envelopes": np.full((3, 9, 3), math.inf)}, "envelopes must be finite"),
        ({"envelopes": -np.ones((3, 9, 3))}, r">= 0.*class 0, bin 0, axis 0"),
        ({"envelopes": [[1, 2], [3]]}, "envelopes must be an array of numbers"),
        ({"position_m": np.zeros((3, 8))}, r"position_m must have shape \(3, 9\)"),
        ({"heading_rad": np.zeros((2, 9))}, r"heading_rad must have shape \(3, 9\)"),
        ({"position_m": np.full((3, 9), math.nan)}, "position_m must be finite"),
        ({"heading_rad": -np.ones((3, 9))}, r"heading_rad must be >= 0.*class 0, bin 0"),
        (
            {"position_m": _DROP},
            r"position_m must be non-decreasing .*class 1 \(change\), bins 3-4",
        ),
        ({"estimation_position_m": -1e-3}, "estimation_position_m must be >= 0"),
        ({"estimation_heading_rad": math.nan}, "estimation_heading_rad must be finite"),
        ({"source": 3}, "source must be a string"),
    ],
)
def test_a_bad_budget_is_refused(changes: dict[str, object], match: str) -> None:
    with pytest.raises(TransientBudgetError, match=match):
        TransientBudget(**_args(**changes))  # type: ignore[arg-type]


def test_bad_questions_are_refused() -> None:
    b = random_budget(0)
    with pytest.raises(TransientBudgetError, match=r"class must be 0 \(hold\), 1 .* or 2"):
        b.heading_bound_rad(3, np.array([0.0]))
    with pytest.raises(TransientBudgetError, match="class must be"):
        b.position_bound_m(True, np.array([0.0]), np.array([0.0]))
    with pytest.raises(TransientBudgetError, match="t_s must be finite and >= 0"):
        b.heading_bound_rad(0, np.array([-0.1]))
    with pytest.raises(TransientBudgetError, match=r"t_s must have shape \(T,\)"):
        b.heading_bound_rad(0, np.zeros((2, 2)))
    with pytest.raises(TransientBudgetError, match="speed_mps must be finite and >= 0"):
        b.position_bound_m(0, np.array([-0.1]), np.array([1.0]))
    with pytest.raises(TransientBudgetError, match=r"speed_mps must have shape \(m,\)"):
        b.position_bound_m(0, 0.1, np.array([1.0]))
    assert issubclass(TransientBudgetError, ValueError)
