"""What `hil inspect` and `hil plot` share for bags holding only the lab's topics.

``--scenario`` names the scenario such a bag cannot name (arena, targets,
obstacles drawn from it); ``--config`` the vessel config whose topic names and
arena transform it was recorded with (:func:`hil.replay.lab.load_lab_config`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hil.bag.run_data import RunData
    from hil.scenarios import Scenario


def add_lab_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare ``--scenario`` and ``--config``."""
    parser.add_argument(
        "--scenario",
        default=None,
        metavar="SCENARIO",
        help="scenario to draw the run in (default: the one the log names; a bag holding "
        "only the lab's topics names none)",
    )
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="vessel config (TOML): the lab's topic names and arena transform of a bag "
        "holding only the lab's topics (default: the lab's topics, identity transform)",
    )


def load_for_view(
    log: Path, scenario_name: str | None, config: Path | None
) -> tuple[RunData, Scenario | None, list[str]]:
    """Load a run to draw; return it, its scenario (None when unknown) and notes to print.

    Raises:
        hil.bag.errors.ReplayError: The log cannot be read, or holds nothing to draw.
        ValueError: The config or the scenario cannot be read (naming it).
    """
    from hil.bag.run_data import load_run
    from hil.replay.lab import load_lab_config, with_scenario_layout
    from hil.scenarios import ScenarioError, load_scenario
    from hil.views.controller_view import scenario_for

    lab, _ = load_lab_config(config)
    data = load_run(log, lab).require_motion()
    notes = [*data.warnings, *data.notes]
    if scenario_name is not None:
        try:
            scenario: Scenario | None = load_scenario(scenario_name)
        except ScenarioError as err:
            raise ValueError(f"scenario {scenario_name!r} cannot be loaded: {err}") from err
    else:
        scenario, note = scenario_for(data)
        if note and data.lab_only:
            note = (
                "a bag holding only the lab's topics names no scenario: pass --scenario NAME "
                "to draw the arena, targets and obstacles"
            )
        if note:
            notes.append(note)
    if data.lab_only:
        if scenario is not None:
            data = with_scenario_layout(data, scenario)
        notes.append(
            "a lab bag: no decisions recorded; `hil replay --scenario NAME --rerun DIR LOG` "
            "writes an .rrd with the decisions of the stack re-run on its pose and IMU"
        )
    return data, scenario, notes
