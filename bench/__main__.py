"""Run the benchmarks: `python -m bench` (all) or `python -m bench NAME [args]`.

Each benchmark module defines `main(argv: list[str] | None) -> int` and prints its
figures beside a baseline measured in the same run.
"""

from __future__ import annotations

import importlib
import sys

BENCHMARKS = {
    "docking": "bench.docking",
    "lowlevel": "bench.lowlevel",
    "observer": "bench.observer",
    "synthesis": "bench.synthesis",
    "latency": "bench.layout_latency",
    "recorder": "bench.recorder",
    "replay": "bench.replay",
    "rerun_export": "bench.rerun_export",
    "dask": "bench.dask",
    "qtm_path": "bench.qtm_path",
}


def main(argv: list[str]) -> int:
    """Run one benchmark with its own arguments, or all of them with none."""
    if argv and argv[0] in {"-h", "--help"}:
        print(__doc__)
        print("benchmarks:", ", ".join(BENCHMARKS))
        return 0
    if argv:
        name, rest = argv[0], argv[1:]
        if name not in BENCHMARKS:
            print(f"unknown benchmark {name!r}; choose from {', '.join(BENCHMARKS)}")
            return 2
        return int(importlib.import_module(BENCHMARKS[name]).main(rest))
    status = 0
    for name, module in BENCHMARKS.items():
        print(f"\n=== bench {name} ===", flush=True)
        status |= int(importlib.import_module(module).main([]))
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
