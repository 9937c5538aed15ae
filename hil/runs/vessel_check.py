"""`hil vessel --check`: a preflight that listens to the vessel's feeds and moves nothing.

It synthesizes the scenario's controller as `hil vessel` does, then listens on the
configured pose, IMU and obstacle topics (no publisher is created), and judges what it
heard against the premises of the guarantee (:mod:`hil.runs.feed_check`): rate, jitter,
latency, clock, frame id, NaN share and QoS per topic, and where the last pose puts the
vessel (inside the arena, on which cell, winning from there at rest).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass

import numpy as np

from hil.adapters.qtm import QtmPoseSource
from hil.adapters.ros_listen import Heard, RosListener
from hil.controllers.symbolic import NoWinningSetError
from hil.core.clock import WallClock
from hil.core.pose_feeds import PoseFeed, pose_feed
from hil.core.samples import PoseSample
from hil.runs.feed_check import (
    CheckLine,
    PositionFinding,
    judge_imu_feed,
    judge_pose_feed,
    judge_position,
    judge_publishers,
    series_of,
)
from hil.runs.qtm_check import judge_qtm_feed, listen_qtm
from hil.runs.stack_assembly import synthesizer_for
from hil.runs.vessel_config import VesselConfig
from hil.runtime.assembly import LayoutSolver, layout_from_scenario
from hil.runtime.protocols import SymbolicController
from hil.scenarios import Scenario, load_scenario

__all__ = ["CheckReport", "check_vessel"]


@dataclass(frozen=True)
class CheckReport:
    """The preflight's verdict, line by line.

    Attributes:
        lines: Every judged line, in the order printed.
        time_source: "wall time" or "/clock (sim time)".
        listened_s: How long the topics were listened to (s).
    """

    lines: tuple[CheckLine, ...]
    time_source: str
    listened_s: float

    @property
    def ok(self) -> bool:
        """Whether every line passed."""
        return all(line.ok for line in self.lines)


def _obstacle_lines(heard: Heard) -> list[CheckLine]:
    count = len(heard.arrival_ns)
    finite = all(heard.finite)
    return [CheckLine(heard.topic, "messages", f"{count} received, "
                      f"{'all' if finite else 'not all'} finite",
                      "tracked obstacles reported, finite", count > 0 and finite,
                      "check the obstacle tracker publishes (ros2 topic hz " + heard.topic + ")")]


def _position(pose: PoseSample | None, scenario: Scenario,
              controller: SymbolicController | None) -> PositionFinding:
    if pose is None:
        return PositionFinding(None, False, -1, math.inf)
    eta = np.array([pose.x_m, pose.y_m, pose.yaw_rad])
    arena = scenario.arena
    inside = arena.x_min_m <= pose.x_m <= arena.x_max_m and \
        arena.y_min_m <= pose.y_m <= arena.y_max_m
    if controller is None:
        return PositionFinding((pose.x_m, pose.y_m, pose.yaw_rad), inside, -1, math.inf)
    cell = controller.locate(eta)
    # At rest, as the vessel waits for the run: the first decision's value from nu = 0.
    value = controller.value(eta, controller.nearest_input(np.zeros(3)), True) \
        if cell >= 0 else math.inf
    return PositionFinding((pose.x_m, pose.y_m, pose.yaw_rad), inside, cell, float(value))


def _ros_pose_lines(listener: RosListener, config: VesselConfig,
                    feed: PoseFeed) -> list[CheckLine]:
    """Judge the ROS pose topic: its publishers and its feed."""
    ros = config.ros
    pose = listener.heard("pose")
    assert pose is not None
    return [judge_publishers(pose.topic, listener.publishers(pose.topic),
                             ros.best_effort_sensors, pose.qos_refusals),
            *judge_pose_feed(series_of(pose), ros.pose_frame_id, ros.use_sim_time, feed)]


def _premise_line(feed: PoseFeed, scenario: Scenario) -> CheckLine:
    """Say which pose feed's premises are in force and the estimation bound they give."""
    budget = scenario.transient
    return CheckLine("pose feed", "premise in force",
                     f'pose_feed = "{feed.name}": {feed.premise_text()}; estimation bound '
                     f"{1e3 * budget.estimation_position_m:.1f} mm, "
                     f"{1e3 * budget.estimation_heading_rad:.1f} mrad",
                     "the feed lines below hold it", True)


def check_vessel(config: VesselConfig, seconds: float,
                 progress: Callable[[str], None]) -> CheckReport:
    """Listen for `seconds` of wall time and judge the feeds and the vessel's pose.

    Args:
        config: The vessel configuration (`hil vessel --config`).
        seconds: How long to listen (s), > 0.
        progress: Receives a line per step.

    Raises:
        hil.scenarios.ScenarioError: The config's scenario cannot be read.
        hil.adapters.ros.RosBackendError: ROS 2 cannot start.
    """
    feed = pose_feed(config.pose_feed)
    scenario = load_scenario(config.scenario).for_pose_feed(feed.name)
    ros = config.ros
    clock = "/clock (sim time)" if ros.use_sim_time else "wall time"
    controller: SymbolicController | None = None
    # Discovery runs while the controller is synthesized; the feeds are timed after it,
    # as the synthesis holds the interpreter and would delay the arrivals it records.
    with RosListener(ros) as listener, ExitStack() as closing:
        qtm_clock = WallClock()
        qtm = None if config.qtm is None else \
            closing.enter_context(QtmPoseSource(config.qtm, qtm_clock))
        progress(f"synthesizing the controller for the {scenario.name!r} scenario...")
        synthesizer = synthesizer_for(scenario, threads=config.loop.synthesis_threads)
        no_controller = ""
        try:
            controller = LayoutSolver(scenario, synthesizer)(layout_from_scenario(scenario))
        except NoWinningSetError as err:
            no_controller = str(err)
        topics = ([] if qtm else [ros.topics.pose]) + [ros.topics.imu] + (
            [ros.topics.obstacles] if ros.topics.obstacles else [])
        progress(f"listening on {', '.join(topics)}{' and QTM' if qtm else ''} for "
                 f"{seconds:g} s (ROS domain {listener.domain_id}, {clock}); no thruster "
                 "publisher is created")
        # A driver that was just started may take seconds to deliver (discovery, its own
        # start-up): the window opens at the first pose, waited for as long as it lasts.
        first = qtm.wait_first(seconds) if qtm else listener.wait_first("pose", seconds)
        if not first:
            progress(f"no pose after {seconds:g} s; listening anyway")
        listener.restart()
        start_s = time.monotonic()
        window = None
        if qtm is None:
            time.sleep(seconds)
        else:
            window = listen_qtm(qtm, qtm_clock, seconds)
        listened_s = time.monotonic() - start_s
        imu = listener.heard("imu")
        assert imu is not None
        lines = [_premise_line(feed, scenario)]
        if window is not None and config.qtm is not None:
            lines += judge_qtm_feed(window, config.qtm, feed)
            last = window.last
        else:
            lines += _ros_pose_lines(listener, config, feed)
            last = listener.last_pose()
        lines += [judge_publishers(imu.topic, listener.publishers(imu.topic),
                                   ros.best_effort_sensors, imu.qos_refusals),
                  *judge_imu_feed(series_of(imu), ros.use_sim_time)]
        obstacles = listener.heard("obstacles")
        if obstacles is not None:
            lines += [judge_publishers(obstacles.topic, listener.publishers(obstacles.topic),
                                       ros.best_effort_sensors, obstacles.qos_refusals),
                      *_obstacle_lines(obstacles)]
        finding = _position(last, scenario, controller)
    lines += judge_position(finding, config.scenario)
    if no_controller:
        lines.append(CheckLine("arena", "controller", no_controller,
                               "a controller for the scenario", False,
                               "check the scenario's obstacles and target"))
    return CheckReport(tuple(lines), clock, listened_s)
