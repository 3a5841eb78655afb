"""The README's five-minute tour, run as written, command by command.

The commands come from the fenced ``sh`` blocks of the README's "Five-minute
tour" section (and its subsections), so this test breaks when the README
changes into something that does not work. They run in a fresh copy of the
repository (its tracked files, in a temporary folder, with ``.venv`` linked to
this checkout's virtualenv so that ``. .venv/bin/activate`` works as written).

How each command is run, from what it is:

- ``. FILE``: sourced before every later command;
- ``COMMAND &``: started in the background, stopped with SIGTERM at the end
  of its block;
- a ``--display`` run: in a terminal (tmux) until its live tree shows an
  active state (for the drone mission: until it takes off), then Ctrl+C,
  which must stop it cleanly (exit status 130);
- ``hfsmc view PORT``: until it has attached and printed the component's
  start, then Ctrl+C;
- anything else: to completion, exit status 0.

The one liberty taken: the monitor port of a block (``--monitor 8765``) is
replaced in the whole block by a free one, so that the test never takes a
port someone else uses. The simulator keeps its fixed ports, as written; when
they are taken, the drone block is skipped and says so.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.support import Tmux, free_port, wait_for_line

ACTIVE = re.compile(r"● \w+")  # the live tree shows an active state
# A state a --display run must reach before the test presses Ctrl+C, by model (follow_colors:
# climbing, below TakeOff, which is active from the start while it waits for the vehicle).
MILESTONES = {"follow_colors": re.compile(r"● (Climb|Mission)\b")}
SIM_PORTS = (("udp", 14550), ("tcp", 8554))  # hfsmc sim's defaults: MAVLink, camera


@dataclass
class Block:
    heading: str
    commands: list[str]
    files: dict[str, str] = field(default_factory=dict)  # what the reader is told to write


def tour() -> list[Block]:
    """The sh blocks of the README's tour section, their commands without comments."""
    text = (ROOT / "README.md").read_text("utf-8")
    start = text.index("\n## Five-minute tour\n")
    end = text.find("\n## ", start + 1)
    section = text[start:end if end > 0 else len(text)]
    blocks: list[Block] = []
    heading = "Five-minute tour"
    files: dict[str, str] = {}
    for m in re.finditer(r"^#{2,3} ([^\n]+)$|^( *)```(sh|yaml)\n(.*?)^ *```", section, re.M | re.S):
        if m.group(1):
            heading = m.group(1)
            continue
        body = "".join(line.removeprefix(m.group(2)) + "\n" for line in m.group(4).splitlines())
        if m.group(3) == "yaml":  # `# file: PATH` first: the reader writes it there
            first, _, rest = body.partition("\n")
            if first.startswith("# file: "):
                files[first.removeprefix("# file: ").strip()] = rest
            continue
        lines = (re.sub(r"(^|\s+)#\s.*$", "", line).strip() for line in body.splitlines())
        blocks.append(Block(heading, [line for line in lines if line], files))
        files = {}
    return blocks


BLOCKS = tour()


def test_the_tour_is_found() -> None:
    assert len(BLOCKS) >= 3
    commands = [c for b in BLOCKS for c in b.commands]
    assert commands[0] == ". .venv/bin/activate"
    assert any(c.startswith("hfsmc view --replay") for c in commands)


def port_free(kind: str, port: int) -> bool:
    with socket.socket(type=socket.SOCK_DGRAM if kind == "udp" else socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@dataclass
class Copy:
    """A fresh copy of the repository and what runs in it."""

    root: Path
    env: dict[str, str]
    prelude: list[str] = field(default_factory=list)
    background: list[tuple[str, subprocess.Popen[bytes], Path]] = field(default_factory=list)
    terminals: list[Tmux] = field(default_factory=list)
    ran: list[str] = field(default_factory=list)  # the blocks run to their end

    def shell(self, command: str) -> list[str]:
        """bash running ``command`` after the sourced files, as the README's shell would."""
        return ["bash", "--norc", "--noprofile", "-c", " && ".join([*self.prelude, command])]

    def log(self, name: str) -> Path:
        """Beside the copy, not in it: the tour must leave only what it says it writes."""
        return self.root.parent / f"tour-{name}-{time.monotonic_ns()}.log"


@pytest.fixture(scope="module")
def fresh(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Copy]:
    root = tmp_path_factory.mktemp("tour") / "hfsmc"
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                             check=True, timeout=60).stdout.decode().split("\0")
    for name in filter(None, tracked):
        source = ROOT / name
        if source.is_file():  # a file deleted in this checkout is not part of the copy
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, root / name)
    (root / ".venv").symlink_to(ROOT / ".venv")
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "TMUX", "NO_COLOR")}
    env["XDG_CACHE_HOME"] = str(root.parent / "cache")  # `hfsmc run` builds there
    copy = Copy(root, env)
    yield copy
    stop_background(copy)
    for t in copy.terminals:
        t.kill()


def stop_background(copy: Copy) -> list[str]:
    """SIGTERM to what a block left running; what each said, for failed checks."""
    problems = []
    for command, proc, log in copy.background:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
        try:
            status = proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            status = proc.wait(timeout=10)
        if status not in (0, 143, -signal.SIGTERM):
            problems.append(f"`{command}` exited {status}:\n{log.read_text(errors='replace')}")
    copy.background.clear()
    return problems


# -- the runners -----------------------------------------------------------------------------

def run_to_completion(copy: Copy, command: str) -> None:
    timeout = 900 if "--compile" in command or "cmake" in command else 180
    proc = subprocess.run(copy.shell(command), cwd=copy.root, env=copy.env, capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    said = f"`{command}` exited {proc.returncode}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    assert proc.returncode == 0, said
    words = shlex.split(command)
    if words[:2] == ["hfsmc", "check"] and "--dump-ir" not in words:
        assert proc.stdout == proc.stderr == "", said  # silent when clean
    for flag, value in itertools.pairwise(words):
        if flag == "-o":
            assert (copy.root / value).exists(), said
    if "--trace" in words and words[words.index("--trace") + 1] == "-":
        assert json.loads(proc.stdout.splitlines()[-1])["ev"] == "stop", said
    if words[:3] == ["hfsmc", "view", "--replay"]:
        assert re.search(r"^\s*[\d.]+\s+stop \(", proc.stdout, re.M), said


def spawn(copy: Copy, command: str, log: Path) -> subprocess.Popen[bytes]:
    """``command`` started in the copy's shell, in its own session, its output in ``log``."""
    with log.open("wb") as out:
        return subprocess.Popen(copy.shell("exec " + command), cwd=copy.root, env=copy.env,
                                stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)


@contextlib.contextmanager
def interrupted_at_the_end(copy: Copy, command: str, log: Path,
                           ) -> Iterator[subprocess.Popen[bytes]]:
    """``command`` running for the body of the ``with``, then stopped as Ctrl+C stops it: it
    must end with status 0 or 130."""
    proc = spawn(copy, command, log)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        status = proc.wait(timeout=30)
    assert status in (0, 130), log.read_text(errors="replace")


def start_in_background(copy: Copy, command: str) -> None:
    log = copy.log("background")
    proc = spawn(copy, command, log)
    copy.background.append((command, proc, log))
    monitor = re.search(r"--monitor (\d+)", command)
    if monitor:  # a person types the next command slower than a test does
        wait_for_port(int(monitor.group(1)), proc, log)
    time.sleep(1.0)
    assert proc.poll() is None, f"`{command}` ended at once:\n{log.read_text(errors='replace')}"


def wait_for_port(port: int, proc: subprocess.Popen[bytes], log: Path) -> None:
    """Until the component listens on its monitor port (its log may go to a file of its own)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"ended before it listened:\n{log.read_text(errors='replace')}"
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.5):
            return
        time.sleep(0.1)
    pytest.fail(f"nothing listens on {port} after 60 s:\n{log.read_text(errors='replace')}")


def run_display_in_a_terminal(copy: Copy, command: str) -> None:
    t = Tmux(shlex.join(copy.shell("exec " + command)), copy.root)
    copy.terminals.append(t)
    model = next((name for name in MILESTONES if name in command), None)
    wanted = MILESTONES[model] if model else ACTIVE
    timeout = 300 if "hfsmc run" in command else 60  # a drone waits for the simulator
    t.wait(lambda s: bool(wanted.search(s)) or "EXIT=" in s, timeout=timeout)
    screen = t.screen()
    assert "EXIT=" not in screen, f"`{command}` ended before Ctrl+C:\n{screen}"
    t.keys("C-c")  # "Ctrl+C stops it cleanly"; a drone lands first
    screen = t.wait(lambda s: "EXIT=" in s, timeout=180)
    assert "EXIT=130" in screen, f"`{command}` after Ctrl+C:\n{screen}"
    assert "stopped (sigint)" in screen, screen


def attach_a_viewer(copy: Copy, command: str) -> None:
    log = copy.log("view")
    with interrupted_at_the_end(copy, command, log) as proc:
        text = wait_for_line(log, re.compile(r"^\s*[\d.]+\s+(start \w+ )?in \w", re.M), proc,
                             timeout=60, step=0.1).string
        assert "hfsmc view: connected to 127.0.0.1:" in text, text


def serve_a_web_view(copy: Copy, command: str) -> None:
    """`hfsmc view --web`: it says where it serves, the page loads, Ctrl+C stops it."""
    log = copy.log("web")
    with interrupted_at_the_end(copy, command, log) as proc:
        text = wait_for_line(log, re.compile(r"web view on (http://127\.0\.0\.1:\d+/)"), proc,
                             timeout=60, step=0.1).string
        url = re.search(r"web view on (http://\S+/\?token=[\w-]+) ", text)
        assert url, text
        # The token's URL sets a cookie and redirects to the page, which needs it (web.md, Trust).
        browser = urllib.request.build_opener(urllib.request.HTTPCookieProcessor())
        with browser.open(url.group(1), timeout=10) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        if "--replay" not in command:
            wait_for_line(log, re.compile(r"hfsmc view: connected to 127\.0\.0\.1:"), proc,
                          timeout=30, step=0.1)


def run(copy: Copy, command: str) -> None:
    words = shlex.split(command)
    if words[0] in (".", "source"):
        run_to_completion(copy, command)
        copy.prelude.append(command)
    elif command.endswith("&"):
        start_in_background(copy, command[:-1].strip())
    elif "--display" in words:
        run_display_in_a_terminal(copy, command)
    elif words[:2] == ["hfsmc", "view"] and "--web" in words:
        serve_a_web_view(copy, command)
    elif words[:2] == ["hfsmc", "view"] and "--replay" not in words:
        attach_a_viewer(copy, command)
    else:
        run_to_completion(copy, command)


@pytest.mark.timeout(1500)
@pytest.mark.parametrize("block", BLOCKS, ids=[re.sub(r"\W+", "-", b.heading).strip("-").lower()
                                                for b in BLOCKS])
def test_the_tour_runs_as_written(fresh: Copy, block: Block) -> None:
    commands = block.commands
    if any(c.startswith("hfsmc sim") for c in commands):
        busy = [f"{kind} {port}" for kind, port in SIM_PORTS if not port_free(kind, port)]
        if busy:
            # The README names these ports: the tour cannot run as written without them.
            pytest.fail(f"the simulator's ports the README names are in use ({', '.join(busy)}): "
                        "stop what holds them and run again")
    ports = {m.group(1) for c in commands for m in re.finditer(r"--(?:monitor|web) (\d+)", c)}
    for port in ports:
        mine = str(free_port())
        commands = [re.sub(rf"\b{port}\b", mine, c) for c in commands]
    # The tour is one shell session: what earlier blocks sourced holds here too.
    earlier = BLOCKS[:BLOCKS.index(block)]
    fresh.prelude = [c for b in earlier for c in b.commands if c.split()[0] in (".", "source")]
    for name, text in block.files.items():
        (fresh.root / name).parent.mkdir(parents=True, exist_ok=True)
        (fresh.root / name).write_text(text)
    try:
        for command in commands:
            run(fresh, command)
        fresh.ran.append(block.heading)
    finally:
        problems = stop_background(fresh)
        for t in fresh.terminals:
            t.kill()
        fresh.terminals.clear()
    assert not problems, "\n".join(problems)


# What the tour may leave in the repository: build/ (git-ignored), the files the README tells the
# reader to write, and the virtualenv. Anything else would show in `git status` after the tour.
ALLOWED = ("build/", ".venv")


def test_the_tour_leaves_the_repository_clean(fresh: Copy) -> None:
    """After every block above (this test runs last in its file): `git status` would show only
    the files the reader wrote, nothing that hfsmc or a component left behind."""
    written = {name for b in BLOCKS for name in b.files}
    assert written, "the tour writes no file of its own"
    assert len(fresh.ran) == len(BLOCKS), f"run the whole tour first (ran: {fresh.ran})"
    tracked = set(filter(None, subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True,
        timeout=60).stdout.decode().split("\0")))
    left = sorted(os.path.relpath(os.path.join(folder, name), fresh.root)
                  for folder, _, names in os.walk(fresh.root) for name in names)
    extra = [name for name in left if name not in tracked and name not in written
             and not name.startswith(ALLOWED) and "__pycache__" not in name]
    assert not extra, f"the tour left files that git would show: {extra}"
