"""What produced a recorded run, as stored in the bag's ``custom_data``.

Read back by :attr:`hil.bag.reader.BagInfo.run`; written by the recorder into
``metadata.yaml`` at open.
"""

from __future__ import annotations

import subprocess
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from hil import __version__

FORMAT_VERSION = "3"
"""Version of hil's log layout, stored as ``custom_data['hil_format']``.

3: the lab's topics hold the lab's types and frames (pose as received in the lab's
frame, unstamped Twist and Wrench commands); hil's arena pose, estimate and stamped
commands on ``/hil/...``; ``/tf_static``; rosbag2's metadata record in each split.
2: hil's arena pose, estimate and stamped commands on the lab's topic names. Both
are read (:data:`hil.bag.topics.STREAM_TOPICS`)."""


def git_revision(cwd: Path | None = None) -> str:
    """Return the git commit of `cwd` (default: this package's checkout), or "" if none."""
    where = cwd if cwd is not None else Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=where,
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""


@dataclass(frozen=True, slots=True)
class RunInfo:
    """What produced a run, stored in the bag's ``custom_data``.

    Attributes:
        scenario_file: Path or name of the scenario file.
        scenario_hash: Hash of the scenario's content.
        seed: Random seed of the run; None when not seeded.
        hil_version: Version of the hil package that recorded.
        git_revision: Git commit of the code that recorded ("" when unknown).
        backend: World the run ran in: "sim", "ros", "log" or "" when unknown.
        run_spec: JSON of the simulated run's specification (start, faults, obstacle
            motions), so a replay can re-simulate it exactly; "" on the vessel.
    """

    scenario_file: str = ""
    scenario_hash: str = ""
    seed: int | None = None
    hil_version: str = __version__
    git_revision: str = ""
    backend: str = ""
    run_spec: str = ""

    @staticmethod
    def current(
        scenario_file: str = "",
        scenario_hash: str = "",
        seed: int | None = None,
        backend: str = "",
        run_spec: str = "",
    ) -> RunInfo:
        """Describe a run of this checkout (version and git revision filled in)."""
        return RunInfo(
            scenario_file, scenario_hash, seed, __version__, git_revision(), backend, run_spec
        )

    def custom_data(self) -> dict[str, str]:
        """Return the string key-value pairs stored in ``metadata.yaml``."""
        return {
            "hil_format": FORMAT_VERSION,
            "scenario_file": self.scenario_file,
            "scenario_hash": self.scenario_hash,
            "seed": "" if self.seed is None else str(self.seed),
            "hil_version": self.hil_version,
            "git_revision": self.git_revision,
            "backend": self.backend,
            "run_spec": self.run_spec,
        }

    @staticmethod
    def from_custom_data(data: Mapping[str, str]) -> RunInfo | None:
        """Read a run description back; None when the data was not written by hil."""
        if "hil_format" not in data:
            return None
        seed = data.get("seed", "")
        return RunInfo(
            scenario_file=data.get("scenario_file", ""),
            scenario_hash=data.get("scenario_hash", ""),
            seed=int(seed) if seed.lstrip("-").isdigit() else None,
            hil_version=data.get("hil_version", ""),
            git_revision=data.get("git_revision", ""),
            backend=data.get("backend", ""),
            run_spec=data.get("run_spec", ""),
        )
