"""No function in hil/ is over 80 lines (tools/long_functions.py), but the named exemptions."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from tests.tools.tool_loader import load_tool

HIL = Path(__file__).resolve().parents[2] / "hil"


@pytest.fixture(scope="module")
def lf() -> ModuleType:
    return load_tool("long_functions")


def test_no_function_in_hil_is_over_80_lines(lf: ModuleType) -> None:
    found = lf.long_functions([HIL], 80)
    offenders = [f"{f.path}:{f.line} {f.name} ({f.length} lines)" for f in found if not f.exempt]
    assert offenders == []


def test_it_counts_from_the_def_line_to_the_last(lf: ModuleType, tmp_path: Path) -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(80))
    source = tmp_path / "m.py"
    source.write_text(f"@decorator\ndef long_one():\n{body}\n\n\ndef short():\n    return 1\n")
    found = lf.long_functions([tmp_path], 80)
    assert [(f.name, f.line, f.length) for f in found] == [("long_one", 2, 81)]
    assert lf.long_functions([tmp_path], 81) == []
    assert lf.main(["--max", "80", str(tmp_path)]) == 1
    assert lf.main(["--max", "81", str(tmp_path)]) == 0
