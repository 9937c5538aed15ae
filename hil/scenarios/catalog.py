"""Find a scenario: the packaged ones by name, any other by the path of its TOML file.

Packaged scenarios live beside this module (``hil/scenarios/*.toml``);
``load_scenario("paper")`` finds one by name, any other argument is read as a path.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from hil.scenarios.errors import ScenarioError
from hil.scenarios.parse import parse_scenario
from hil.scenarios.scenario import Scenario

__all__ = ["load_scenario", "packaged_scenarios"]


def packaged_scenarios() -> list[str]:
    """Return the names of the scenarios shipped with the package."""
    folder = resources.files("hil") / "scenarios"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a packaged scenario by name ("paper", "coarse") or any TOML file by path.

    Raises:
        ScenarioError: The file is missing, is not TOML, or fails validation.
    """
    text: str
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as err:
            raise ScenarioError(f"cannot read scenario file {str(path)!r}: {err}") from err
        default = path.stem
    else:
        name = str(name_or_path)
        resource = resources.files("hil") / "scenarios" / f"{name}.toml"
        if not resource.is_file():
            raise ScenarioError(
                f"no scenario named {name!r} (packaged: {', '.join(packaged_scenarios())}; "
                "or give a path to a .toml file)"
            )
        text = resource.read_text(encoding="utf-8")
        default = name
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"scenario {str(name_or_path)!r} is not valid TOML: {err}") from err
    return parse_scenario(data, default)
