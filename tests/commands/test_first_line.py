"""Every long command says what it is doing before its heavy imports (the README's commands).

The first line is printed by :class:`hil.commands.stages.Stages`; here each command is
stopped right after it, in a fresh interpreter, and the modules loaded by then are listed:
none of numpy, numba, scipy, rerun, rosbags or matplotlib may be among them (their import
is what takes seconds). No wall-clock assertion: the order is what is checked.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("numpy", "numba", "scipy", "rerun", "rosbags", "matplotlib")

_PROBE = """
import sys
from hil.commands import stages

def say(self, text):
    heavy = sorted(m for m in {heavy!r} if m in sys.modules)
    print(f"FIRST {{self.prog}}: {{text}} | heavy={{heavy}}", flush=True)
    raise SystemExit(0)

stages.Stages.say = say
from hil.cli import main
main({argv!r})
print("NO FIRST LINE", flush=True)
"""

COMMANDS = [
    ["synth", "coarse"],
    ["run", "coarse", "--no-record"],
    ["campaign", "paper", "-n", "2"],
    ["sweep", "sweep.toml"],
    ["replay", "logs/coarse-default-seed0"],
    ["inspect", "logs/coarse-default-seed0", "-o", "x.rrd"],
    ["plot", "logs/paper-default-seed0", "-o", "x.png"],
    ["judge", "logs/coarse-default-seed0", "--truth", "truth.csv"],
    ["record-suite"],
]


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: a[0])
def test_the_first_line_comes_before_any_heavy_import(argv: list[str]) -> None:
    probe = _PROBE.format(heavy=HEAVY, argv=argv)
    proc = subprocess.run(
        [sys.executable, "-c", probe],
        capture_output=True, text=True, cwd=ROOT, timeout=120, check=False,
    )  # fmt: skip
    first = proc.stdout.splitlines()[0] if proc.stdout else proc.stderr[-500:]
    assert first.startswith(f"FIRST hil {argv[0]}: "), first
    assert first.endswith("| heavy=[]"), first
