#!/usr/bin/env python3
"""Set up the project's virtual environment on first use, then run a task in it.

Needs only Python 3.11 and pip. Usage:

    python3 tools/dev.py run [hil run arguments]   # dock the simulated vessel
    python3 tools/dev.py test [pytest arguments]   # ruff, mypy, import layers, tests
    python3 tools/dev.py bench [bench arguments]   # benchmarks under bench/
    python3 tools/dev.py hil ARGS...               # any hil command

The environment lives in `.venv/` and is reinstalled only when pyproject.toml
changes (its hash is kept in `.venv/.hil-installed`).
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
STAMP = VENV / ".hil-installed"


def _venv_bin(name: str) -> Path:
    return VENV / ("Scripts" if os.name == "nt" else "bin") / name


def _extras() -> str:
    # The ROS 2 Jazzy wheels on PyPI exist for x86_64 Linux only; elsewhere (the
    # vessel's aarch64 Pi) the ROS backend uses the system's rclpy. Dask (campaigns on a
    # cluster) and qtm-rt (the direct Qualisys feed) are pure Python: everywhere, so
    # their tests run.
    if platform.system() == "Linux" and platform.machine() == "x86_64":
        return ".[dev,ros,dask,qtm]"
    return ".[dev,dask,qtm]"


def ensure_venv() -> None:
    """Create `.venv` and install the package with pinned dependencies, if stale."""
    if sys.version_info < (3, 11):  # noqa: UP036 - this script may be run by an older python3
        sys.exit(f"hil needs Python 3.11 or newer, this is {platform.python_version()}")
    wanted = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    wanted += " " + _extras()
    if STAMP.exists() and STAMP.read_text().strip() == wanted:
        return
    if not _venv_bin("python").exists():
        print(f"[dev] creating virtual environment in {VENV}", flush=True)
        venv.EnvBuilder(with_pip=True).create(VENV)
    print(f"[dev] installing hil{_extras()[1:]} with pinned dependencies (about a minute)",
          flush=True)
    pip = [str(_venv_bin("python")), "-m", "pip", "--disable-pip-version-check"]
    log = VENV / "pip-install.log"
    with log.open("w") as out:
        status = subprocess.call([*pip, "install", "-e", _extras()], cwd=ROOT, stdout=out,
                                 stderr=subprocess.STDOUT)
    if status != 0:
        tail = log.read_text().splitlines()[-30:]
        sys.exit("\n".join(["[dev] pip install failed; last lines of " + str(log), *tail]))
    STAMP.write_text(wanted + "\n")


def main(argv: list[str]) -> int:
    """Dispatch one task; return its exit status."""
    if not argv or argv[0] not in {"run", "test", "bench", "hil"}:
        print(__doc__)
        return 2
    task, rest = argv[0], argv[1:]
    ensure_venv()
    env = dict(os.environ)
    env.setdefault("PYTHONHASHSEED", "0")
    py = str(_venv_bin("python"))
    if task == "run":
        return subprocess.call([str(_venv_bin("hil")), "run", *rest], cwd=ROOT, env=env)
    if task == "hil":
        return subprocess.call([str(_venv_bin("hil")), *rest], cwd=ROOT, env=env)
    if task == "bench":
        return subprocess.call([py, "-m", "bench", *rest], cwd=ROOT, env=env)
    steps = [
        [py, "-m", "ruff", "check", "hil", "tests", "bench", "tools"],
        [py, "-m", "mypy"],
        [str(_venv_bin("lint-imports"))],  # layers import downward only, no cycles
        [py, "-m", "pytest", "-n", "2", "--cov=hil", "--cov-report=term:skip-covered", *rest],
    ]
    for step in steps:
        print(f"[dev] {' '.join(Path(step[0]).name if i == 0 else a for i, a in enumerate(step))}",
              flush=True)
        status = subprocess.call(step, cwd=ROOT, env=env)
        if status != 0:
            return status
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
