"""Premises per pose feed: ``[pose_feeds.NAME]`` tables and the budget in force."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.core.pose_feeds import DEFAULT_POSE_FEED
from hil.scenarios import ScenarioError, parse_scenario

PAPER_TOML = Path(__file__).parents[2] / "hil" / "scenarios" / "paper.toml"
ROS = "ros-10hz-receive-stamped"


def _paper(feeds: dict[str, Any] | None = None) -> dict[str, Any]:
    data = tomllib.loads(PAPER_TOML.read_text(encoding="utf-8"))
    data.pop("pose_feeds", None)
    if feeds is not None:
        data["pose_feeds"] = feeds
    return data


def _wider(data: dict[str, Any]) -> dict[str, Any]:
    table = dict(data["transient"])
    table["estimation_position_m"] = 0.02
    table["estimation_heading_rad"] = 0.03
    return table


def test_the_feed_in_force_sets_the_estimation_bound_and_the_digest() -> None:
    data = _paper()
    plain = parse_scenario(_paper())
    scenario = parse_scenario(_paper({ROS: _wider(data)}))
    # Tables for other feeds leave the scenario's digest (its logs, its caches) alone.
    assert scenario.digest() == plain.digest()
    assert scenario.for_pose_feed(DEFAULT_POSE_FEED) is scenario
    ros = scenario.for_pose_feed(ROS)
    assert ros.transient.estimation_position_m == 0.02
    assert ros.transient.estimation_heading_rad == 0.03
    np.testing.assert_array_equal(ros.transient.position_m, plain.transient.position_m)
    assert ros.digest() != plain.digest()  # another controller: another hash


def test_a_feed_without_premises_is_refused_naming_the_table() -> None:
    scenario = parse_scenario(_paper())
    with pytest.raises(ScenarioError, match=r"no premises for pose feed 'ros-10hz-receive-"
                       r"stamped'.*add a \[pose_feeds.ros-10hz-receive-stamped\] table"):
        scenario.for_pose_feed(ROS)


@pytest.mark.parametrize(("feeds", "match"), [
    ({"ros-1hz": {}}, r"pose_feeds.ros-1hz': not a pose feed.*known: ros-10hz"),
    ({DEFAULT_POSE_FEED: {}}, r"qtm-100hz's are \[transient\]"),
    ({ROS: 3}, r"'pose_feeds.ros-10hz-receive-stamped' must be a table"),
])
def test_bad_pose_feed_tables_are_refused(feeds: dict[str, Any], match: str) -> None:
    with pytest.raises(ScenarioError, match=match):
        parse_scenario(_paper(feeds))


def test_a_pose_feed_budget_is_checked_as_transient_is() -> None:
    table = _wider(_paper())
    table["estimation_position_m"] = -1.0
    with pytest.raises(ScenarioError, match=r"pose_feeds.ros-10hz-receive-stamped.'estimation"):
        parse_scenario(_paper({ROS: table}))
