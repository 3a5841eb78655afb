"""`hfsmc check` knows the interfaces' methods in Python snippets (E148, E149; C++ snippets
are compiled), and `hfsmc test` names the interface when a run calls a method it lacks."""

from __future__ import annotations

from pathlib import Path

from hfsmc.pipeline import compile_file
from tests.support import hfsmc

HEAD = """\
hfsm: 1
name: m
language: python
interfaces:
  drone: {type: mavlink}
  cam: {type: camera}
  topic: {type: ros_topic}
"""


def model(entry: str, functions: str = "") -> str:
    body = "".join(f"      {line}\n" for line in entry.splitlines())
    funcs = "functions: |\n" + "".join(f"  {ln}\n" for ln in functions.splitlines()) \
        if functions else ""
    return (HEAD + funcs + "initial: A\nstates:\n  A:\n    entry: |\n" + body
            + "    transitions: [{to: B, when: drone.armed() and cam.ok()}]\n  B: {final: true}\n")


def found(text: str) -> list[tuple[str, int, int, str]]:
    return [(d.code, d.span.line, d.span.col, d.message)
            for d in compile_file("m.yaml", text).diagnostics if d.code in ("E148", "E149")]


def test_every_right_use_passes() -> None:
    text = model("""\
drone.set_mode("GUIDED")
drone.takeoff(alt=3.0)
drone.set_velocity(1.0, 0.0, vz=0.5, yaw_rate=0.0)
drone.goto(*[1.0, 2.0, 3.0])
drone.set_velocity(**{"vx": 1, "vy": 0, "vz": 0, "yaw_rate": 0})
log(drone.name + cam.url + str(drone.position()[0]) + drone.last_ack("land"))
img = cam.frame()
f = drone.land
f()
topic.anything()
drone._snap""", functions="""\
def helper(drone):
    return drone.fly_to(1)
def other():
    cam = object()
    return cam.frames()""")
    assert found(text) == []


def test_unknown_methods_and_wrong_counts_at_their_names() -> None:
    text = model("""\
drone.fly_to(10, 0, 5)
x = cam.frames()
drone.go_to(1, 2, 3)
drone.takeoff()
drone.goto(1, 2, 3, 4, 5)
drone.takeoff(3, alt=3)
drone.land(now=True)
y = drone.altitud
z = cam.url()""")
    assert found(text) == [
        ("E148", 12, 13, "`drone` (mavlink interface) has no method `fly_to`"),
        ("E148", 13, 15, "`cam` (camera interface) has no method `frames`"),
        ("E148", 14, 13, "`drone` (mavlink interface) has no method `go_to`"),
        ("E149", 15, 13, "`drone.takeoff` takes 1 argument (alt): missing `alt`"),
        ("E149", 16, 13, "`drone.goto` takes 4 arguments (north, east, alt, heading): 5 given"),
        ("E149", 17, 13, "`drone.takeoff` takes 1 argument (alt): `alt` given twice"),
        ("E149", 18, 13, "`drone.land` takes no arguments: no parameter `now`"),
        ("E148", 19, 17, "`drone` (mavlink interface) has no method `altitud`"),
        ("E148", 20, 15, "`cam.url` is an attribute in Python, not a method: write `cam.url` "
                         "(C++: `cam.url()`)"),
    ]
    notes = {d.message: d.notes for d in compile_file("m.yaml", text).diagnostics}
    assert notes["`cam` (camera interface) has no method `frames`"] == ("did you mean `frame`?",)
    assert notes["`drone` (mavlink interface) has no method `go_to`"] == (
        "`go_to` is the C++ name; in Python the method is `goto`",)
    assert "goto(north, east, alt, heading)" in \
        notes["`drone` (mavlink interface) has no method `fly_to`"][0]


def test_a_when_and_a_do_are_checked_too() -> None:
    text = HEAD + """\
initial: A
states:
  A:
    transitions:
      - {to: B, when: drone.conected(), do: drone.arm(1)}
  B: {final: true}
"""
    assert [(c, ln, col) for c, ln, col, _ in found(text)] == [("E148", 12, 29), ("E149", 12, 51)]


def test_a_run_names_the_interface_and_the_model_line(tmp_path: Path) -> None:
    """A use `check` cannot see (the interface under another name): the run fails, and the
    report names the interface and the model line first, not the test double's class."""
    (tmp_path / "fly.yaml").write_text("""\
hfsm: 1
name: fly
language: python
interfaces:
  drone: {type: mavlink}
period: 50ms
initial: Go
states:
  Go:
    entry: |
      d = drone
      d.fly_to(10, 0, 5)
    transitions: [{to: Done, after: 1s}]
  Done: {final: true}
""")
    (tmp_path / "fly_test.yaml").write_text("""\
name: fly
model: fly.yaml
until: 5s
inputs:
  drone:
    - {at: 0s, connected: true}
expect:
  - entered: Done
""")
    r = hfsmc("test", "fly_test.yaml", cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    first = lines.index("fly_test.yaml: an error in a snippet (an `error` expectation allows it)")
    assert lines[first + 1] == ("    fly.yaml:12:7: error: AttributeError: the mavlink interface "
                                "`drone` has no method or attribute `fly_to` (docs/interfaces.md)")
    assert "Fake" not in r.stdout and "__getattr__" not in r.stdout
