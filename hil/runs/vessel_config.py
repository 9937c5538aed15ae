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
    """

    scenario: str = "paper"
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
        if qtm is None:
            return config
        if not isinstance(qtm, dict):
            raise ConfigError(f"qtm: must be a table ([qtm]), got {qtm!r}")
        return replace(config, qtm=qtm_config_from_table(qtm, config.ros.transform))


def config_text(config: VesselConfig) -> str:
    """Return `config` as commented TOML: every key, its value and its meaning.

    The ``[qtm]`` table, absent unless the pose comes from QTM, is printed commented out
    with its defaults; its transform is ``[ros.transform]``'s, not a key of its own.
    """
    return config_toml(config, optional={"qtm": QtmConfig}, skip=frozenset({"qtm.transform"}))
