"""``./seapup help`` and the command tables are generated from the commands' own parsers
(:mod:`seapup_bringup.cli_usage`): the committed files match what the parsers generate, and the help names
every option and subcommand each parser accepts."""
from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from seapup_bringup import cli, cli_usage

ROOT = Path(__file__).resolve().parents[1]


def test_the_committed_usage_files_are_what_the_parsers_generate():
    stale = [str(p.relative_to(ROOT)) for p in cli_usage.stale_files(ROOT)]
    assert stale == [], (f"{', '.join(stale)} differ from the commands' parsers; regenerate with: "
                         f'eval "$(./seapup env)" && {cli_usage.REGENERATE}')


def _options(parser: argparse.ArgumentParser):
    """Each option (its spellings) and subcommand a parser accepts (``-h`` aside), from argparse's own actions."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (name,)
                yield from _options(sub)
        elif isinstance(action, argparse._HelpAction):
            continue
        elif action.option_strings:
            yield tuple(action.option_strings)


@pytest.mark.parametrize("name", list(cli.COMMANDS))
def test_the_help_line_of_a_command_names_every_option_its_parser_accepts(name):
    line = cli.usage_lines()[name]
    words = set(line.replace("[", " ").replace("]", " ").replace("|", " ").split())
    missing = [o for o in _options(cli_usage.parser_of(cli.COMMANDS[name])) if not words & set(o)]
    assert missing == [], f"./seapup help omits {missing} of {name}"


def test_the_options_the_hand_written_help_missed_are_listed():
    """The usage lines written by hand had drifted (issue 40): these options existed but were not shown."""
    help_text = " ".join(cli.usage().split())
    for command, option in [("demo", "--view-port"), ("demo", "--rate"), ("ident", "residuals"),
                            ("replay", "--view"), ("replay", "--json"), ("bench", "--config"), ("bench", "--steps"),
                            ("bench", "--no-campaign"), ("campaign", "--connect-timeout")]:
        assert option in cli.usage_lines()[command], (command, option)
    assert "mfol|explicit|gmv" not in help_text   # a closed list of three, while five controllers are registered


@pytest.mark.process
def test_help_answers_with_the_standard_library_only(tmp_path):
    """The registry is read before the bootstrap: cli.py and its usage file alone give the full help."""
    import shutil
    import subprocess
    import sys
    for name in ("cli.py", "cli_usage.json"):
        shutil.copy(Path(cli.__file__).with_name(name), tmp_path / name)
    run = subprocess.run([sys.executable, "-S", "-I", str(tmp_path / "cli.py"), "help"], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert cli.usage_lines()["campaign"].split()[0] in run.stdout and "--connect-timeout" in run.stdout
