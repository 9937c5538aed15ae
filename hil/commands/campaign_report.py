"""The report of a campaign or sweep: the table beside the paper, JSON, failures, exit status.

Shared by ``hil campaign`` and ``hil sweep``: the success rate, the docking-time
distribution beside the paper's tank figures, the least hull clearance, the tracking
error and the guarantee's violations on the true state (tube exits, successor misses,
value not decreasing, centre in an inflated obstacle, hull contact or outside the
arena, and the broken premises: late intervals, estimation), for all runs, those
started at rest and those started moving.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.commands.common import EXIT_CLUSTER_LOST, EXIT_STOPPED
from hil.commands.executor_cli import failure_lines

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from hil.runs.campaign import CampaignResult, CampaignRun, CampaignStats
    from hil.runs.sim_run import SimRunSpec


def _guarantee_rows(table: Table, groups: list[list[CampaignRun]]) -> None:
    """Add the guarantee's rows: intervals with a violation (worst size) per group."""
    from hil.runs.guarantee import GuaranteeViolations

    totals = [GuaranteeViolations.total(g for _, g in runs) for runs in groups]
    rows = (
        ("tube exits (worst m)", "tube_exits", "worst_tube_exit_m", "{:.3f}"),
        ("successor misses (worst m)", "successor_misses", "worst_successor_miss_m", "{:.3f}"),
        ("  heading misses at tau (worst deg)", None, "worst_heading_miss_rad", "deg"),
        ("value not decreasing", "value_not_decreasing", None, ""),
        ("centre in inflated obstacle (depth m)", "inflated_obstacle",
         "worst_inflated_depth_m", "{:.3f}"),
        ("hull contact (penetration m)", "hull_contacts", "worst_hull_penetration_m", "{:.3f}"),
        ("hull outside arena (worst m)", "hull_outside_arena", "worst_hull_outside_m", "{:.3f}"),
        ("late intervals (worst s)", "late_intervals", "worst_late_s", "{:.2f}"),
        ("estimate in another cell (worst m)", "estimation_misses", "worst_estimation_m",
         "{:.4f}"),
    )
    table.add_row("judged intervals", *(f"{t.intervals}" for t in totals), "-")
    for label, count, worst, fmt in rows:
        cells = []
        for t in totals:
            size = "" if worst is None else getattr(t, worst)
            if fmt == "deg":
                cells.append(f"{math.degrees(float(size)):.1f}")
                continue
            text = str(getattr(t, count)) if count is not None else ""
            if worst is not None:
                text += f" ({fmt.format(size)})"
            cells.append(text)
        table.add_row(label, *cells, "-")
    table.add_row("runs with a violation",
                  *(str(sum(g.violations > 0 for _, g in runs)) for runs in groups), "-")


def _per_policy(runs: list[CampaignRun], specs: list[SimRunSpec]) -> dict[str, Any]:
    """Return the figures of each selection policy's runs (``--select``), by name."""
    from hil.runs.campaign import CampaignStats
    from hil.runs.guarantee import GuaranteeViolations

    out: dict[str, Any] = {}
    for name in dict.fromkeys(spec.select for spec in specs):
        mine = [run for run, spec in zip(runs, specs, strict=True) if spec.select == name]
        stats = CampaignStats.of([summary for summary, _ in mine])
        out[name] = {
            **asdict(stats),
            "winning_starts": stats.winning_starts,
            "guarantee": asdict(GuaranteeViolations.total(g for _, g in mine)),
            "runs_with_violations": sum(g.violations > 0 for _, g in mine),
        }
    return out


def report(outcome: CampaignResult, *, command: str, title: str, console: Console,
           as_json: bool, extra: dict[str, Any], results: Path | None) -> int:
    """Print the campaign's table (and JSON with `as_json`); return the exit status.

    0: every run finished, and every run winning at its first decision docked without
    contact and without a guarantee violation; 1 otherwise (a failed run included);
    130 stopped by Ctrl-C; 3 the Dask scheduler went away (both keep the finished runs
    in `results`, reported too).
    """
    from hil.runs.campaign import CampaignStats
    from hil.runs.guarantee import GuaranteeViolations

    results_note = f"; results: {results} (continue with --resume {results})" if results else ""
    for line in failure_lines(command, list(outcome.failures), results):
        print(line, file=sys.stderr)
    runs, specs = outcome.runs, outcome.specs
    if not runs:
        why = outcome.reason or "every run failed"
        print(f"hil {command}: no run finished ({why}){results_note}", file=sys.stderr)
        return _stopped_status(outcome.reason) if outcome.stopped else 1
    groups = [runs,
              [r for r, s in zip(runs, specs, strict=True) if s.start_velocity is None],
              [r for r, s in zip(runs, specs, strict=True) if s.start_velocity is not None]]
    all_stats = [CampaignStats.of([summary for summary, _ in g]) for g in groups]
    stats = all_stats[0]
    console.print(_figures_table(outcome, title, groups, all_stats))
    if outcome.resumed or outcome.retried:
        console.print(f"{outcome.resumed} run(s) read back from the results file, "
                      f"{outcome.retried} re-run after their worker died")
    if as_json:
        print(json.dumps(_report_json(outcome, groups, all_stats, extra, results)))
    if outcome.stopped:
        print(f"hil {command}: {outcome.reason}: stopped after {len(runs)} of "
              f"{outcome.planned} runs; the figures above are the finished runs{results_note}",
              file=sys.stderr)
        return _stopped_status(outcome.reason)
    if results is not None:
        console.print(f"results: {results}")
    violations = GuaranteeViolations.total(g for _, g in runs).violations
    ok = (stats.docked == stats.winning_starts and stats.contacts == 0 and violations == 0
          and not outcome.failures)
    return 0 if ok else 1


def _figures_table(outcome: CampaignResult, title: str, groups: list[list[CampaignRun]],
                   all_stats: list[CampaignStats]) -> Table:
    """Return the figures of all runs, those started at rest and moving, beside the paper's."""
    from rich.table import Table

    from hil.runs.campaign import PAPER_TANK_MINUTES

    runs, specs, stats = outcome.runs, outcome.specs, all_stats[0]
    stopped = (f", STOPPED after {len(runs)} of {outcome.planned} runs"
               if outcome.stopped else "")
    failed = f", {len(outcome.failures)} FAILED" if outcome.failures else ""
    table = Table(title=f"{title}, {stats.runs} runs{stopped}{failed}")
    table.add_column("measure")
    for name in ("all", "at rest", "moving"):
        table.add_column(f"hil (sim), {name}", justify="right")
    table.add_column("paper", justify="right")
    table.add_row("docked, of the runs winning at their first decision",
                  *(f"{s.docked}/{s.winning_starts}" for s in all_stats), "5/5 sim, 10/10 tank")
    table.add_row("first decision not winning (though drawn winning where it is by then)",
                  *(str(s.lost_at_start) for s in all_stats), "-")
    table.add_row("runs with hull contact", *(str(s.contacts) for s in all_stats), "-")
    table.add_row("docking time mean (min..max)",
                  *("{:.2f} ({:.2f}..{:.2f}) min".format(*s.docking_min) for s in all_stats),
                  "{:.2f} ({:.2f}..{:.2f}) min".format(*PAPER_TANK_MINUTES))
    table.add_row("least hull clearance", *(f"{s.min_clearance_m:.3f} m" for s in all_stats), "-")
    if stats.moving_obstacle_runs or stats.stale_stops:
        table.add_row("runs with moving obstacles / re-syntheses / stale-report stops",
                      *(f"{s.moving_obstacle_runs} / {s.resyntheses} / {s.stale_stops}"
                        for s in all_stats), "-")
    for axis, (label, paper) in enumerate(zip(("surge m/s", "sway m/s", "yaw deg/s"),
                                              (0.00768, 0.00431, 0.62108), strict=True)):
        table.add_row(f"tracking RMS, {label}",
                      *(f"{s.tracking_rms[axis]:.5f}" for s in all_stats), f"{paper}")
    _guarantee_rows(table, groups)
    policies = _per_policy(runs, specs)
    if set(policies) != {"J"}:
        for name, figures in policies.items():
            table.add_row(f"--select {name}: docked / runs with a violation",
                          f"{figures['docked']}/{figures['winning_starts']} / "
                          f"{figures['runs_with_violations']}", "-", "-", "-")
    table.add_row("wall time per run", *(f"{s.wall_s_mean:.2f} s" for s in all_stats), "-")
    return table


def _report_json(outcome: CampaignResult, groups: list[list[CampaignRun]],
                 all_stats: list[CampaignStats], extra: dict[str, Any],
                 results: Path | None) -> dict[str, Any]:
    """Return the JSON report: the figures of each group, the guarantee's, each run's."""
    from hil.runs.guarantee import GuaranteeViolations

    runs, specs = outcome.runs, outcome.specs
    per_run = [{"seed": spec.seed, "scenario": spec.scenario, "start": list(spec.start or ()),
                "start_velocity": None if spec.start_velocity is None
                else list(spec.start_velocity),
                "select": spec.select,
                "docked": summary.docked, "docking_time_s": summary.docking_time_s,
                "guarantee": asdict(g)}
               for spec, (summary, g) in zip(specs, runs, strict=True)]
    return {**asdict(all_stats[0]), **extra,
            "at_rest": asdict(all_stats[1]), "moving_starts": asdict(all_stats[2]),
            "guarantee": asdict(GuaranteeViolations.total(g for _, g in runs)),
            "guarantee_at_rest": asdict(GuaranteeViolations.total(g for _, g in groups[1])),
            "guarantee_moving": asdict(GuaranteeViolations.total(g for _, g in groups[2])),
            "runs_with_violations": sum(g.violations > 0 for _, g in runs),
            "planned_runs": outcome.planned, "stopped": outcome.stopped,
            "failed_runs": [{"run": f.index, "error": f.error, "spec": f.spec}
                            for f in outcome.failures],
            "results": None if results is None else str(results),
            "per_policy": _per_policy(runs, specs),
            "per_run": per_run}


def _stopped_status(reason: str) -> int:
    return EXIT_STOPPED if "Ctrl-C" in reason else EXIT_CLUSTER_LOST
