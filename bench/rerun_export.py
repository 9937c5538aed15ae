"""Benchmark `hil inspect`: convert a 3-minute run to .rrd; time and file size.

Targets (issue 7): a 3-minute run converts in <= 5 s to a file of <= 50 MB.
Baseline, measured in the same run on the same log: Rerun's own importer,
``rerun mcap convert`` (one process per MCAP split, the way it must be called),
which shows poses and messages but not the arena, controller view or blueprint.

Usage: ``python -m bench rerun_export [--log BAG] [--repeat N]``. Without
``--log`` a real 3-minute run is simulated first (paper scenario; the dock hold
is longer than the run, so it goes the full 180 s; re-synthesis on layout changes
only, to keep the set-up short).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

RUN_S = 180.0
TARGET_S = 5.0
TARGET_MB = 50.0


@dataclass(frozen=True)
class Row:
    """One measured way to convert the log."""

    name: str
    seconds: float
    megabytes: float
    note: str = ""


def _make_run(out: Path) -> None:
    from hil.runs.sim_run import SimRunSpec, run_in_sim
    from hil.runtime.settings import LoopConfig

    loop = LoopConfig(resynthesis_period_s=None, dock_hold_s=RUN_S, max_duration_s=RUN_S)
    summary = run_in_sim(SimRunSpec(scenario="paper", seed=0, out_dir=out, loop=loop))
    print(f"made a {summary.duration_s:.0f}-s run ({summary.end_reason}) in {summary.wall_s:.1f} s")


def _hil_inspect(log: Path, out: Path, winning_set: bool) -> tuple[float, str]:
    """Convert as `hil inspect` does; return the wall time and the stage breakdown."""
    from hil.bag.run_data import load_run
    from hil.views.controller_view import controller_view, scenario_for
    from hil.views.rerun_export import write_rrd

    start = time.perf_counter()
    run = load_run(log)
    loaded = time.perf_counter()
    scenario, _ = scenario_for(run)
    view = controller_view(run, scenario) if winning_set and scenario is not None else None
    viewed = time.perf_counter()
    stats = write_rrd(run, out, scenario, view)
    end = time.perf_counter()
    note = (
        f"read {loaded - start:.2f} s, re-synthesis {viewed - loaded:.2f} s, "
        f"rerun {end - viewed:.2f} s; {stats.rows} rows"
    )
    return end - start, note


def _mcap_convert(log: Path, out_dir: Path) -> tuple[float, float, str]:
    """Run `rerun mcap convert` on every split; return wall time, MB and a note."""
    rerun = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    files = sorted(log.glob("*.mcap")) if log.is_dir() else [log]
    start = time.perf_counter()
    total = 0
    for n, mcap in enumerate(files):
        out = out_dir / f"mcap_{n}.rrd"
        subprocess.run(
            [rerun, "mcap", "convert", str(mcap), "-o", str(out)], check=True, capture_output=True
        )
        total += out.stat().st_size
    return time.perf_counter() - start, total / 1e6, f"{len(files)} process(es)"


def _best(rows: list[Row]) -> Row:
    return min(rows, key=lambda r: r.seconds)


def main(argv: list[str] | None = None) -> int:
    """Measure and print the table; return 1 when a target is missed."""
    parser = argparse.ArgumentParser(prog="python -m bench rerun_export")
    parser.add_argument(
        "--log", type=Path, default=None, help="an existing run (default: make one)"
    )
    parser.add_argument("--repeat", type=int, default=3, help="best of N (default 3)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_rerun_") as tmp:
        root = Path(tmp)
        log = args.log
        if log is None:
            log = root / "run"
            _make_run(log)
        from hil.bag.reader import describe

        info = describe(log)
        print(
            f"log: {log}: {info.message_count} messages, {info.duration_ns / 1e9:.1f} s, "
            f"{sum(p.stat().st_size for p in Path(log).glob('*.mcap')) / 1e6:.2f} MB MCAP"
        )
        rows: list[Row] = []
        for name, winning in (("hil inspect", True), ("hil inspect --no-winning-set", False)):
            runs = []
            for i in range(max(args.repeat, 1)):
                out = root / f"hil_{winning}_{i}.rrd"
                seconds, note = _hil_inspect(log, out, winning)
                runs.append(Row(name, seconds, out.stat().st_size / 1e6, note))
            rows.append(_best(runs))
        baseline = _best(
            [
                Row("rerun mcap convert (baseline)", *_mcap_convert(log, root))
                for _ in range(max(args.repeat, 1))
            ]
        )
        rows.append(baseline)
    print(f"{'conversion':<32} {'time (s)':>9} {'x baseline':>10} {'size (MB)':>10}  note")
    for row in rows:
        ratio = row.seconds / baseline.seconds if baseline.seconds > 0 else float("nan")
        print(
            f"{row.name:<32} {row.seconds:>9.2f} {ratio:>10.2f} {row.megabytes:>10.2f}  {row.note}"
        )
    full = rows[0]
    ok = full.seconds <= TARGET_S and full.megabytes <= TARGET_MB
    print(
        f"target: <= {TARGET_S:g} s and <= {TARGET_MB:g} MB for a 3-minute run: "
        f"{'met' if ok else 'MISSED'} ({full.seconds:.2f} s, {full.megabytes:.2f} MB)"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
