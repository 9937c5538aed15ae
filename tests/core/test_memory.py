"""The memory check a large allocation asks first: the system's and the process's limits."""

from __future__ import annotations

import subprocess
import sys

import pytest

from hil.core.memory import available_bytes, require_bytes


def test_what_fits_passes_and_what_does_not_names_both_sizes() -> None:
    available = available_bytes()
    if available is None:
        pytest.skip("this system does not tell its available memory")
    require_bytes(available // 2, "half of it")
    message = r"^a solve needs about 1048576\.0 GiB, [0-9.]+ GiB available$"
    with pytest.raises(MemoryError, match=message):
        require_bytes(2**50, "a solve")


def test_an_address_space_limit_bounds_what_is_available() -> None:
    limit = 3 << 30
    code = (
        "import resource; "
        f"resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit})); "
        "from hil.core.memory import available_bytes; "
        "print(resource.getrlimit(resource.RLIMIT_AS)[0], available_bytes())"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    ).stdout.split()
    if out[0] != str(limit):
        pytest.skip("RLIMIT_AS is not applied here (qemu user-mode emulation ignores it)")
    assert 0 < int(out[1]) < limit
