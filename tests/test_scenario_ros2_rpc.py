"""`hfsmc test` scenarios that script action servers and service responses (docs/testing.md,
"Action servers and service responses"): accepted with feedback over time then succeeded,
rejected, aborted with its result, cancelled by the model, a server that appears late, no
server then the time limit, a call answered late or never; each scenario run against the
Python model and its C++ twin (the same file, the same outcome); every mistake at its place."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hfsmc.errors import Diagnostics
from hfsmc.pipeline import compile_file
from hfsmc.scenario import check_against_model, read_scenario

MODEL = """\
hfsm: 1
name: nav
imports:
  - from nav2_msgs.action import NavigateToPose
  - from std_srvs.srv import Trigger
parameters:
  cancel_after: {type: float, default: -1.0}
variables: {dist: -1.0}
interfaces:
  robot:
    type: ros2
    actions:
      navigate: {name: navigate_to_pose, type: nav2_msgs/action/NavigateToPose, timeout: 3s}
    services:
      reset: {name: reset_odometry, type: std_srvs/srv/Trigger, timeout: 1s}
initial: Reset
states:
  Reset:
    entry: robot.call("reset", Trigger.Request())
    transitions:
      - to: Go
        when: robot.call_status("reset") == "done" and robot.response("reset").success
      - {to: Failed, when: robot.call_status("reset") == "timeout"}
  Go:
    entry: |
      goal = NavigateToPose.Goal()
      goal.pose.pose.position.x = 2.0
      robot.send_goal("navigate", goal)
    during: |
      f = robot.feedback("navigate")
      if f is not None and f.distance_remaining != dist:
          dist = f.distance_remaining
          log(f"dist {dist:g}")
      if cancel_after >= 0 and elapsed() >= cancel_after and robot.goal_status("navigate") == "executing":
          robot.cancel("navigate")
    transitions:
      - {to: Done, when: robot.goal_status("navigate") == "succeeded"}
      - to: Failed
        when: robot.goal_status("navigate") in ("rejected", "aborted", "canceled", "timeout")
  Failed:
    entry: |
      r = robot.result("navigate")
      log(f"{robot.goal_status('navigate')} {robot.call_status('reset')} {r.error_code if r is not None else '-'}")
    transitions: [{to: End, after: 100ms}]
  Done: {final: true}
  End: {final: true}
"""

# The C++ twin of MODEL: the same states, log lines and commands.
MODEL_CPP = """\
hfsm: 1
name: nav_cpp
language: cpp
imports: ["<cstdio>", "<string>"]
parameters:
  cancel_after: {type: float, default: -1.0}
variables: {dist: -1.0}
interfaces:
  robot:
    type: ros2
    actions:
      navigate: {name: navigate_to_pose, type: nav2_msgs/action/NavigateToPose, timeout: 3s}
    services:
      reset: {name: reset_odometry, type: std_srvs/srv/Trigger, timeout: 1s}
functions: |
  static std::string g(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%g", v);
    return text;
  }
initial: Reset
states:
  Reset:
    entry: robot.call("reset", std_srvs::srv::Trigger::Request());
    transitions:
      - to: Go
        when: robot.call_status("reset") == "done" && robot.response("reset")->success
      - {to: Failed, when: robot.call_status("reset") == "timeout"}
  Go:
    entry: |
      nav2_msgs::action::NavigateToPose::Goal goal;
      goal.pose.pose.position.x = 2.0;
      robot.send_goal("navigate", goal);
    during: |
      const auto* f = robot.feedback("navigate");
      if (f != nullptr && f->distance_remaining != dist) {
        dist = f->distance_remaining;
        log("dist " + g(dist));
      }
      if (cancel_after >= 0 && elapsed() >= cancel_after && robot.goal_status("navigate") == "executing")
        robot.cancel("navigate");
    transitions:
      - {to: Done, when: robot.goal_status("navigate") == "succeeded"}
      - to: Failed
        when: robot.goal_status("navigate") == "rejected" || robot.goal_status("navigate") == "aborted" || robot.goal_status("navigate") == "canceled" || robot.goal_status("navigate") == "timeout"
  Failed:
    entry: |
      const auto* r = robot.result("navigate");
      log(robot.goal_status("navigate") + " " + robot.call_status("reset") + " " + (r != nullptr ? std::to_string(r->error_code) : std::string("-")));
    transitions: [{to: End, after: 100ms}]
  Done: {final: true}
  End: {final: true}
"""

RESET = "    - {at: 0s, reset: {response: {success: true}, after: 200ms}}\n"
NAVIGATE = """\
    - at: 0s
      navigate:
        feedback:
          - {after: 0s, fields: {distance_remaining: 2.0}}
          - {after: 1s, fields: {distance_remaining: 1.0}}
        after: 2s
        result: {error_code: 0}
"""


def write(tmp: Path, name: str, inputs: str, expect: str, params: str = "") -> Path:
    """A scenario of both twins (nav.yaml and nav_cpp.yaml beside it)."""
    (tmp / "nav.yaml").write_text(MODEL)
    (tmp / "nav_cpp.yaml").write_text(MODEL_CPP)
    (tmp / f"{name}.yaml").write_text(
        f"model: {{python: nav.yaml, cpp: nav_cpp.yaml}}\nuntil: 5s\n{params}inputs:\n"
        f"  robot:\n{inputs}expect:\n{expect}")
    return tmp / f"{name}.yaml"


def hfsmc_test(cache: Path, *scenarios: Path) -> subprocess.CompletedProcess[str]:
    """`hfsmc test` of the scenarios, one build cache (the C++ twin is compiled once)."""
    return subprocess.run([sys.executable, "-m", "hfsmc", "test", *map(str, scenarios)],
                          capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL,
                          env={**os.environ, "XDG_CACHE_HOME": str(cache)})


CASES = {
    # accepted, feedback over time, succeeded: the goal is sent at 200 ms (the call's answer)
    "succeed": (RESET + NAVIGATE, "", """\
  - {entered: Go, between: [200ms, 200ms]}
  - {log: dist 2, between: [300ms, 300ms]}
  - {log: dist 1, between: [1.2s, 1.2s]}
  - {entered: Done, between: [2.2s, 2.2s]}
"""),
    "reject": (RESET + "    - {at: 0s, navigate: {accept: false}}\n", "",
               "  - {log: rejected done -, between: [300ms, 300ms]}\n"),
    "abort": (RESET + "    - {at: 0s, navigate: {after: 1s, end: aborted, result: "
              "{error_code: 205}}}\n", "", "  - {log: aborted done 205, between: [1.2s, 1.2s]}\n"),
    # the model cancels 500 ms into Go: canceled at the next instant, the default result
    "cancel": (RESET + NAVIGATE, "parameters: {cancel_after: 0.5}\n", """\
  - {command: robot.cancel, between: [700ms, 700ms]}
  - {log: canceled done 0, between: [800ms, 800ms]}
"""),
    # no action server until 1 s: the goal waits for it, then runs its 2 s from there
    "late": (RESET + NAVIGATE.replace("at: 0s", "at: 1s"), "",
             "  - {entered: Done, between: [3s, 3s]}\n"),
    # no action server at all: no_server, then the goal's 3 s time limit
    "none": (RESET, "", "  - {log: timeout done -, between: [3.2s, 3.2s]}\n"),
    # a reset server that answers after the call's 1 s time limit
    "slow": ("    - {at: 0s, reset: {response: {success: true}, after: 2s}}\n", "",
             "  - {log: none timeout -, between: [1s, 1s]}\n"),
}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """Every case's scenario run at once in both languages: (the cache, the output)."""
    tmp = tmp_path_factory.mktemp("servers")
    files = [write(tmp, case, inputs, expect, params)
             for case, (inputs, params, expect) in CASES.items()]
    r = hfsmc_test(tmp / "cache", *files)
    return tmp / "cache", r.stdout + r.stderr


@pytest.mark.parametrize("case", list(CASES))
def test_a_scripted_server_answers_as_a_live_one_in_both_languages(runs: tuple[Path, str],
                                                                   case: str) -> None:
    out = runs[1]
    assert f"{case}.yaml::python PASSED" in out, out
    assert f"{case}.yaml::cpp PASSED" in out, out


def test_a_scripted_server_can_fail_a_scenario_in_both_languages(
        runs: tuple[Path, str], tmp_path: Path) -> None:
    late = write(tmp_path, "late", RESET + NAVIGATE.replace("after: 2s", "after: 2.5s"),
                 "  - {entered: Done, between: [2.2s, 2.2s]}\n")
    # a rejected goal is not a canceled one: the C++ twin is held to the script as well
    rejected = write(tmp_path, "rejected", RESET + "    - {at: 0s, navigate: {accept: false}}\n",
                     "  - {log: canceled done 0, before: 1s}\n")
    r = hfsmc_test(runs[0], late, rejected)
    assert r.returncode == 1, r.stdout + r.stderr
    for name in ("late", "rejected"):
        for lang in ("python", "cpp"):
            assert f"{name}.yaml::{lang} FAILED" in r.stdout, r.stdout


def problems(tmp: Path, inputs: str, model: str) -> list[str]:
    (tmp / "nav.yaml").write_text(MODEL)
    (tmp / "nav_cpp.yaml").write_text(MODEL_CPP)
    (tmp / "sc.yaml").write_text(f"model: {model}\nuntil: 5s\ninputs:\n  robot:\n{inputs}"
                                 "expect:\n  - {entered: Done}\n")
    diags = Diagnostics()
    sc = read_scenario(str(tmp / "sc.yaml"), diags)
    assert sc is not None
    result = compile_file(str(tmp / model))
    assert result.model is not None
    check_against_model(sc, result.model, diags)
    return [f"{d.span.line}:{d.span.col}: {d.code} {d.message}" for d in diags.sorted()]


@pytest.mark.parametrize("model", ["nav.yaml", "nav_cpp.yaml"])
def test_mistakes_are_found_at_their_place(tmp_path: Path, model: str) -> None:
    cases = {
        "navigate: {acept: false}": "5:27: E190 `acept` is not a key of a scripted action server",
        "navigate: {end: exploded}": "5:32: E193 `end` is one of succeeded, aborted (a cancel "
                                     "from the model ends a goal canceled)",
        "navigate: {after: soon}": "5:34: E193 `soon` is not a duration: write 500ms, 2s",
        "navigate: {accept: 1}": "5:35: E191 `accept` is true or false",
        "navigate: {result: {error_cod: 1}}":
            "5:36: E190 nav2_msgs/action/NavigateToPose_Result has no field `error_cod`",
        "navigate: {feedback: [3]}":
            "5:38: E191 a feedback item is `{after: DURATION, fields: {...}}`",
        "reset: {response: {success: 3}}":
            "5:44: E191 `success` (bool) must be true or false, not a number",
        "reset: {after: 1s, answer: {}}":
            "5:35: E190 `answer` is not a key of a scripted service server",
        "dock: {accept: true}": "5:16: E195 the ros2 interface `robot` subscribes to no `dock`",
    }
    for entry, said in cases.items():
        assert problems(tmp_path, f"    - {{at: 0s, {entry}}}\n", model) == [said], entry
