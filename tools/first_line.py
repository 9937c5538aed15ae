"""Time each README command to its first line of output (issue 23: within 1 s).

Every ``hil ...`` command the README shows without placeholders (in its code blocks and
inline), and the commands table's with its placeholders filled from the repository
(``LOG`` = ``logs/coarse-default-seed0``, ...), is started in a scratch folder (with
``logs/`` and a ``vessel.toml`` in it), as on a terminal (``PYTHONUNBUFFERED=1``);
the time from the start to its first line on stdout or stderr is printed, and the
command (its whole process group) is stopped there. A measurement, not a test: run it
on a quiet machine.

    python3 tools/first_line.py [--limit S] [--only WORD]
"""

from __future__ import annotations

import argparse
import os
import re
import select
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HIL = ROOT / ".venv" / "bin" / "hil"
LOG = "logs/coarse-default-seed0"

# The commands table's rows, placeholders filled in.
TABLE = [
    "hil run coarse --seed 3 --out runs/x --json",
    "hil campaign coarse -n 4 --workers 2",
    "hil synth coarse --json",
    f"hil info {LOG} --json",
    "hil vessel --config vessel.toml",
    "hil vessel --print-config --config vessel.toml",
    "hil vessel --check --config vessel.toml --seconds 2",
    "hil sim-vessel coarse --config vessel.toml",
    f"hil judge {LOG} --truth truth.csv --json",
    f"hil replay {LOG}",
    f"hil inspect {LOG} -o run.rrd",
    f"hil plot {LOG} -o run.png",
    f"hil recover {LOG}",
    "hil record-suite --list",
]
# Placeholders (FILE, [--json], ...) and quoted output (`hil run: error: ...`).
_PLACEHOLDER = re.compile(r"[A-Z]{2,}|\[|\.\.\.|\||^hil \S+:")


def readme_commands() -> list[str]:
    """Return the README's ``hil`` commands that run verbatim (no placeholders), in order."""
    text = (ROOT / "README.md").read_text()
    found: list[str] = []
    spans = re.findall(r"`((?:\.venv/bin/)?hil [^`]+)`", text)
    for block in re.findall(r"```(?:bash|sh)\n(.*?)```", text, re.S):
        spans += [line.split("#")[0] for line in block.splitlines()]
    for span in spans:
        command = " ".join(span.split()).replace(".venv/bin/hil ", "hil ")
        if command.startswith("hil ") and not _PLACEHOLDER.search(command) \
                and command not in found:
            found.append(command)
    return found


def first_line_s(command: str, cwd: Path, limit_s: float) -> tuple[float | None, str]:
    """Run `command` in `cwd`; return seconds to its first output line (None: none) and it."""
    argv = [str(HIL), *shlex.split(command)[1:]]
    env = dict(os.environ, PYTHONUNBUFFERED="1", ROS_DOMAIN_ID="231",
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    start = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                            start_new_session=True)
    assert proc.stdout is not None
    buffer = b""
    try:
        while b"\n" not in buffer:
            left = limit_s - (time.perf_counter() - start)
            if left <= 0 or not select.select([proc.stdout], [], [], left)[0]:
                return None, ""
            chunk = os.read(proc.stdout.fileno(), 4096)
            if not chunk:
                return (time.perf_counter() - start, buffer.decode(errors="replace")) \
                    if buffer else (None, "(exited silently)")
            buffer += chunk
        return time.perf_counter() - start, buffer.split(b"\n")[0].decode(errors="replace")
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def main() -> int:
    """Print each command's time to its first line; exit 1 when one took over 1 s."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=float, default=10.0, help="seconds to wait per command")
    parser.add_argument("--only", default="", help="only commands containing this text")
    args = parser.parse_args()
    commands = [c for c in [*readme_commands(), *TABLE] if args.only in c]
    slow = 0
    with tempfile.TemporaryDirectory(prefix="hil-first-line-") as scratch:
        cwd = Path(scratch)
        (cwd / "logs").symlink_to(ROOT / "logs")
        (cwd / "vessel.toml").write_text('scenario = "coarse"\n[ros]\ndomain_id = 231\n')
        (cwd / "sweep.toml").write_text('scenarios = ["coarse"]\nseeds = [0]\n')
        for command in commands:
            seconds, line = first_line_s(command, cwd, args.limit)
            slow += seconds is None or seconds > 1.0
            shown = "  none " if seconds is None else f"{seconds:6.2f}"
            print(f"{shown} s  {'SLOW' if seconds is None or seconds > 1.0 else 'ok  '}  "
                  f"{command}\n            {line[:110]}", flush=True)
    print(f"{len(commands)} commands, {slow} without a first line within 1 s")
    return 1 if slow else 0


if __name__ == "__main__":
    sys.exit(main())
