"""The README's checkable claims against their sources of truth: the demo graph (its launch file), the
mission (config/mission.yaml), the controller registry, the packages and the commands' parsers."""
from __future__ import annotations

import re
from pathlib import Path

import yaml

from seapup_bringup import cli

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
BRINGUP = ROOT / "ros2_ws/src/seapup_bringup"
WORDS = {w: n for n, w in enumerate("zero one two three four five six seven eight nine ten eleven twelve".split())}


def _number_before(text: str, phrase: str) -> int:
    """The number word written just before ``phrase`` (line breaks allowed)."""
    match = re.search(r"\b(\w+)\s+" + r"\s+".join(map(re.escape, phrase.split())), text)
    assert match, f"no '{phrase}' in the text"
    return WORDS[match.group(1).lower()]


def _section(text: str, heading: str) -> str:
    start = text.index(heading)
    end = text.find("\n## ", start + len(heading))
    return text[start:end if end >= 0 else None]


def test_the_velocity_controller_nodes_of_the_demo_graph():
    graph = yaml.safe_load((BRINGUP / "launch/hierarchy.launch.yaml").read_text())
    nodes = [item["node"] for item in graph["launch"] if "node" in item]
    velocity = [n for n in nodes if n["exec"] == "velocity_controller"]
    assert _number_before(README, "`velocity_controller` nodes") == len(velocity)
    assert _number_before(README, "laws in flight") == len(velocity)   # "the controller manager swaps all N laws"
    laws = {p["value"] for n in velocity for p in n.get("param", []) if p.get("name") == "controller_type"}
    described = _section(README, "## What the demo shows")
    assert "MFOL" in described and all(law in described.lower() for law in laws - {"mfol"}), laws


def test_the_numbered_legs_are_the_mission_files():
    legs = yaml.safe_load((BRINGUP / "config/mission.yaml").read_text())["mission"]
    listed = re.findall(r"^(\d+)\. ", _section(README, "## What the demo shows"), re.M)
    assert [int(n) for n in listed] == list(range(1, len(legs) + 1))


def test_the_registered_controllers_are_those_the_docs_list():
    from seapup_common.controllers import available_controllers
    names = set(available_controllers())
    page = (ROOT / "docs/run-result.md").read_text()
    assert _number_before(page, "are registered now") == len(names)
    rows = set(re.findall(r"^\| `(\w+)` \|", page[page.index("are registered now"):], re.M))
    assert names <= rows, names - rows


def test_the_package_count():
    packages = [p.parent.name for p in (ROOT / "ros2_ws/src").glob("*/package.xml")]
    assert _number_before(README, "packages are ordinary") == len(packages)
    assert _number_before(README.replace("Seven colcon", "seven colcon"), "colcon packages under") == len(packages)


def test_every_option_the_readme_shows_is_one_its_command_takes():
    usage = cli.usage_lines()
    shown = re.findall(r"\./seapup ([\w-]+)((?: [^`\n#]*)?)", README)
    assert len(shown) >= 5
    wrong = [(verb, opt) for verb, rest in shown for opt in re.findall(r"(?<![\w-])(--[\w-]+)", rest)
             if verb in usage and opt not in usage[verb].split(" ") and f"[{opt}" not in usage[verb]
             and opt not in ("--help",)]
    assert wrong == []
    assert "(`--view` serves it" in README and "[--view]" in usage["demo"]   # "--view serves it to Foxglove" is demo's


def test_the_two_commands_section_is_kept():
    section = _section(README, "## The two commands")
    assert "./seapup demo" in section and "./seapup test" in section
