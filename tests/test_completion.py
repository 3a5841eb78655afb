"""Shell completion through click's own protocol, as bash asks for it:
``_HFSMC_COMPLETE=bash_complete COMP_WORDS=... COMP_CWORD=... hfsmc`` prints one
``type,value`` line per candidate (README.md, "Shell completion")."""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from hfsmc.cli import main
from hfsmc.commands.completion import component_flags
from tests.conftest import ROOT
from tests.support import write_used_models

HFSMC = Path(sys.executable).parent / "hfsmc"  # the console script: its name sets the variable
BLINKER = "examples/blinker/blinker.yaml"
FOLLOW = "examples/follow_colors/follow_colors.yaml"


def complete(line: str) -> list[str]:
    """The candidates bash gets for the last word of ``line`` (empty after a space): the
    protocol run in this process (the console script itself is run by the bash test)."""
    words = shlex.split(line)
    cword = len(words) if line.endswith(" ") else len(words) - 1
    env = {"_HFSMC_COMPLETE": "bash_complete", "COMP_WORDS": line, "COMP_CWORD": str(cword)}
    result = CliRunner().invoke(main, [], prog_name="hfsmc", env=env)
    assert result.exit_code == 0, result.output
    assert result.stderr == ""  # never a diagnostic or a traceback
    return [line for line in result.stdout.splitlines() if line]  # none: one empty line


def test_diagram_state_completes_the_composite_states_of_the_model() -> None:
    assert complete(f"hfsmc diagram {BLINKER} --state ") == ["plain,Blinking"]
    assert complete(f"hfsmc diagram -o x.svg {FOLLOW} --state Mission/FollowG") == [
        "plain,Mission/FollowGreen", "plain,Mission/FollowGreen2"]


def test_run_focus_after_the_separator_completes_state_paths() -> None:
    assert complete(f"hfsmc run {FOLLOW} -- --focus M") == [
        "plain,Mission", "plain,Mission/FollowGreen", "plain,Mission/FollowBlue",
        "plain,Mission/FollowGreen2", "plain,Mission/FollowRed"]


def test_run_completes_the_component_flags_and_their_values() -> None:
    assert complete(f"hfsmc run {BLINKER} -- --c") == ["plain,--config", "plain,--clock"]
    assert complete(f"hfsmc run {BLINKER} -- --display --clock ") == ["plain,real",
                                                                      "plain,virtual"]
    assert complete(f"hfsmc run {BLINKER} -- --trace ") == ["file,"]


def test_component_flags_are_those_of_the_runtime() -> None:
    flags = component_flags()
    for flag in ("--config", "--param", "--display", "--displaygui", "--focus", "--no-autofocus",
                 "--monitor", "--trace", "--clock", "--until"):
        assert flag in flags


def test_view_focus_completes_from_the_model_or_the_trace(tmp_path: Path) -> None:
    assert complete(f"hfsmc view --model {BLINKER} --focus ") == ["plain,Blinking"]
    trace = tmp_path / "t.trace"
    trace.write_text('{"t":0,"ev":"start","name":"x"}\n{"t":0,"ev":"enter","state":"A"}\n'
                     '{"t":0,"ev":"enter","state":"A/B"}\n{"t":0,"ev":"enter","state":"A/B/C"}\n'
                     'not json\n', "ascii")
    assert complete(f"hfsmc view --replay {trace} --focus ") == ["plain,A", "plain,A/B"]


REGIONS = "examples/regions_arm/regions_arm.yaml"


def test_focus_and_state_complete_regions_and_paths_through_used_files(tmp_path: Path) -> None:
    """A component's --focus and diagram --state take a region; the states of a used
    file's instances continue the using state's path (a nested use too)."""
    regions = ["plain,Working", "plain,Working/Cycle", "plain,Working/Led", "plain,Working/Battery"]
    assert complete(f"hfsmc run {REGIONS} -- --focus ") == regions
    assert complete(f"hfsmc view --model {REGIONS} --focus W") == regions
    assert complete(f"hfsmc diagram {REGIONS} --state Working/") == regions[1:]
    legs = write_used_models(tmp_path)
    used = ["plain,First", "plain,First/Hold", "plain,Second", "plain,Second/Hold"]
    assert complete(f"hfsmc diagram {legs} --state ") == used
    assert complete(f"hfsmc run {legs} -- --focus Se") == used[2:]
    assert complete(f"hfsmc view --model {legs} --focus First/") == ["plain,First/Hold"]


def test_sim_completes_its_own_options_and_files() -> None:
    found = complete("hfsmc sim --w")
    assert "plain,--world" in found and all(c.startswith("plain,--w") for c in found)
    assert complete("hfsmc sim --se") == ["plain,--seed"]
    assert "plain,--drop-link-after" in complete("hfsmc sim --world w.yaml --")
    assert complete("hfsmc sim --world ") == ["file,"]


@pytest.mark.parametrize("line", [
    "hfsmc diagram missing.yaml --state ",
    "hfsmc diagram tests/invalid/bad_indentation.yaml --state ",
    "hfsmc diagram --state ",
    "hfsmc view --replay missing.trace --focus ",
    "hfsmc run missing.yaml -- --focus ",
])
def test_a_model_that_cannot_be_read_completes_nothing(line: str) -> None:
    assert complete(line) == []


def test_commands_and_click_options_still_complete() -> None:
    assert complete("hfsmc di") == ["plain,diagram"]
    assert "plain,--strict" in complete("hfsmc check --s")


def test_bash_runs_the_script_hfsmc_prints_for_it() -> None:
    """The README's `eval "$(_HFSMC_COMPLETE=bash_source hfsmc)"`, then a Tab, in real bash."""
    script = ('eval "$(_HFSMC_COMPLETE=bash_source hfsmc)"; '
              f'COMP_WORDS=(hfsmc diagram {BLINKER} --state ""); COMP_CWORD=4; '
              '_hfsmc_completion hfsmc; printf "<%s>\\n" "${COMPREPLY[@]}"')
    env = {**os.environ, "PATH": f"{HFSMC.parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    proc = subprocess.run(["bash", "--norc", "--noprofile", "-c", script], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "<Blinking>\n"
