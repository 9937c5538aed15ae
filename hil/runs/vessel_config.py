"""`hil vessel`'s config file: scenario, runs folder, [ros], [loop] and an optional [qtm].

Kept apart from the stack (:mod:`hil.runs.vessel_run`), so that reading and printing a
config (``hil vessel --print-config``) imports none of the stack's numerics.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from hil.adapters.qtm import QtmConfig, qtm_config_from_table
from hil.adapters.ros import RosConfig
from hil.core.config import ConfigError, from_table, load_toml
from hil.core.config_doc import config_toml
from hil.core.pose_feeds import DEFAULT_POSE_FEED, POSE_FEEDS, pose_feed
from hil.runs.feed_premise import qtm_rate_refusal
from hil.runtime.settings import LoopConfig

__all__ = ["VesselConfig", "config_text"]


@dataclass(frozen=True)
class VesselConfig:
    """Everything `hil vessel` needs, read from a TOML file.

    Attributes:
        scenario: Packaged scenario name or path of its TOML file.
        runs_dir: Where each run's bag directory is created.
        ros: Topics, QoS, frame transform, domain and clock.
        loop: Loop rate and fault thresholds.
        qtm: With a ``[qtm]`` table, the pose comes straight from Qualisys Track Manager
            (:mod:`hil.adapters.qtm`; IMU and thrusters stay on ROS 2); None: the pose
            topic of ``[ros.topics]``.
        pose_feed: The pose feed whose premises are in force ("qtm-100hz": 100 Hz stamped
            at capture; "ros-10hz-receive-stamped": the mocap4ros2_qualisys driver, 10 Hz
            stamped on receipt, with its wider estimation bound); hil refuses a feed
            slower than it.
    """

    scenario: str = "paper"
    pose_feed: str = DEFAULT_POSE_FEED
    runs_dir: str = "runs"
    ros: RosConfig = field(default_factory=RosConfig)
    loop: LoopConfig = field(default_factory=LoopConfig)
    qtm: QtmConfig | None = None

    def with_ros_args(self, ros_args: tuple[str, ...]) -> VesselConfig:
        """Return this config with `ros_args` (from ``--ros-args``) after ``[ros] ros_args``."""
        if not ros_args:
            return self
        return replace(self, ros=replace(self.ros, ros_args=(*self.ros.ros_args, *ros_args)))

    @staticmethod
    def load(path: str | Path) -> VesselConfig:
        """Read and validate a vessel config file.

        Raises:
            hil.core.config.ConfigError: Naming the key that is wrong.
        """
        table = dict(load_toml(path))
        qtm = table.pop("qtm", None)
        config = from_table(VesselConfig, table)
        if config.pose_feed not in POSE_FEEDS:
            raise ConfigError(f"key 'pose_feed' = {config.pose_feed!r}: one of "
                              f"{', '.join(sorted(POSE_FEEDS))}")
        if qtm is None:
            return config
        if not isinstance(qtm, dict):
            raise ConfigError(f"qtm: must be a table ([qtm]), got {qtm!r}")
        qtm_config = qtm_config_from_table(qtm, config.ros.transform)
        refusal = qtm_rate_refusal(qtm_config, pose_feed(config.pose_feed))
        if refusal:
            raise ConfigError(refusal)
        return replace(config, qtm=qtm_config)


def config_text(config: VesselConfig) -> str:
    """Return `config` as commented TOML: every key, its value and its meaning.

    The ``[qtm]`` table, absent unless the pose comes from QTM, is printed commented out
    with its defaults; its transform is ``[ros.transform]``'s, not a key of its own.
    """
    return config_toml(config, optional={"qtm": QtmConfig}, skip=frozenset({"qtm.transform"}))
