"""A component's start-up, in both languages: --help, --param, --focus, --config.

Every bad flag or configuration is a one-line message and exit status 2, never a
traceback; the Python and the C++ component say the same thing.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cppbuild import Superbuild, need_toolchain

MODEL = """\
hfsm: 1
name: flags{suffix}
language: {lang}
parameters:
  altitude: {{type: float, default: 3.0, description: take-off height in metres}}
  count: {{type: int, default: 2}}
period: 100ms
initial: Mission
states:
  Mission:
    initial: Climb
    states:
      Climb: {{transitions: [{{to: Hold, after: 200ms}}]}}
      Hold: {{final: true}}
    transitions: [{{to: Done, when: done()}}]
  Done: {{final: true}}
"""

BAD_INPUTS: list[tuple[list[str], bytes | None, str]] = [
    # (flags, config file text or None, the message after "NAME: ")
    (["--param", "altitud=3"], None,
     "unknown parameter `altitud`; did you mean `altitude`? (parameters: altitude, count)"),
    (["--param", "count=1.5"], None, "--param: parameter `count` is an int, not `1.5`"),
    (["--focus", "Misson"], None, "--focus Misson: no state `Misson` in {name}; "
     "did you mean `Mission`?"),
    (["--focus", "Mission/Climb"], None,
     "--focus Mission/Climb: state `Mission/Climb` has no sub-automaton to show"),
    (["--focus", "Elsewhere"], None, "--focus Elsewhere: no state `Elsewhere` in {name}"),
    ([], b'{"parameters": {"count": 3}}\n# caf\xe9\n', "{config}:2:6: the configuration is not "
     "UTF-8 text (byte 0xe9); save it as UTF-8"),
    (["--parm", "count=3"], None, "unknown flag --parm; did you mean `--param`?"),
    (["stray"], None, "unexpected argument `stray`"),
    (["--realtime=100"], None, "--realtime: expected a priority from 1 to 99, not `100`"),
    (["--realtime", "fast"], None, "--realtime: expected a priority from 1 to 99, not `fast`"),
    ([], b"[1, 2]\n", "{config}: the configuration must be a mapping"),
    ([], b'{"parameters": [1]}\n', "{config}: `parameters` must be a mapping, not `[1]`"),
    ([], b'{"interfaces": {"drone": 3}}\n', "{config}: interface `drone` must be a mapping, "
     "not `3`"),
]


def run(cmd: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=60,
                          stdin=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def components(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[str]]:
    """The command that runs the model's component, per language (the C++ one built once)."""
    base = tmp_path_factory.mktemp("flags")
    out: dict[str, list[str]] = {}
    py = base / "flags.yaml"
    py.write_text(MODEL.format(suffix="", lang="python"))
    r = run([sys.executable, "-m", "hfsmc", "build", str(py), "-o", str(base / "py")])
    assert r.returncode == 0, r.stderr
    # -I -S: the standard library only, as on a robot without hfsmc
    out["python"] = [sys.executable, "-I", "-S", str(base / "py" / "flags.py")]
    return out


@pytest.fixture(scope="module")
def cpp_component(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    need_toolchain()
    base = tmp_path_factory.mktemp("flags_cpp")
    model = base / "flags_cpp.yaml"
    model.write_text(MODEL.format(suffix="_cpp", lang="cpp"))
    return [str(Superbuild(base / "build", [model]).executable(model))]


@pytest.fixture(params=["python", "cpp"])
def component(request: pytest.FixtureRequest, components: dict[str, list[str]]
              ) -> tuple[list[str], str]:
    if request.param == "cpp":
        return request.getfixturevalue("cpp_component"), "flags_cpp"
    return components["python"], "flags"


def test_help_lists_the_parameters(component: tuple[list[str], str]) -> None:
    cmd, _ = component
    r = run([*cmd, "--help"])
    assert r.returncode == 0, r.stderr
    assert r.stdout.endswith(
        "parameters (set with --param NAME=VALUE or in the configuration):\n"
        "  altitude (float, default 3.0)\n"
        "      take-off height in metres\n"
        "  count (int, default 2)\n"), r.stdout


@pytest.mark.parametrize(("flags", "config", "message"), BAD_INPUTS,
                         ids=[f"case{k}" for k in range(len(BAD_INPUTS))])
def test_bad_flags_and_configs_exit_2_without_traceback(
        component: tuple[list[str], str], tmp_path: Path, flags: list[str], config: bytes | None,
        message: str) -> None:
    cmd, name = component
    args = list(flags)
    path = tmp_path / "config.yaml"
    if config is not None:
        path.write_bytes(config)
        args += ["--config", str(path)]
    r = run([*cmd, *args, "--clock", "virtual"])
    assert r.returncode == 2, r.stderr
    assert r.stderr == f"{name}: {message.format(name=name, config=path)}\n"


def test_config_that_is_a_directory_or_empty(component: tuple[list[str], str],
                                             tmp_path: Path) -> None:
    cmd, name = component
    r = run([*cmd, "--config", str(tmp_path)])
    assert r.returncode == 2
    assert r.stderr == f"{name}: {tmp_path}: cannot read the configuration: Is a directory\n"
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing set here\n")
    r = run([*cmd, "--config", str(empty), "--clock", "virtual", "--focus", "/Mission/"])
    assert r.returncode == 0, r.stderr  # an empty configuration keeps the model's values
    bom = tmp_path / "bom.yaml"
    bom.write_bytes(b'\xef\xbb\xbf{"parameters": {"count": 3}}\n')  # as some editors save it
    r = run([*cmd, "--config", str(bom), "--clock", "virtual", "--param", "altitude=2"])
    assert r.returncode == 0, r.stderr


def test_realtime_flag_is_accepted_and_the_run_goes_on(component: tuple[list[str], str]) -> None:
    cmd, name = component
    for flag in (["--realtime"], ["--realtime=7"], ["--realtime", "7"]):
        r = run([*cmd, *flag, "--clock", "virtual", "--trace", "-"])
        assert r.returncode == 0, r.stderr
        assert r.stdout.endswith('{"t":300,"ev":"stop","reason":"final"}\n'), r.stdout
        # allowed (root, CAP_SYS_NICE): nothing said; else the one line of the next test
        assert r.stderr == "" or r.stderr.startswith(f"{name}: warning: --realtime: refused "), r.stderr


def _unprivileged() -> None:
    """In the child: SCHED_FIFO and locked memory refused, even to root."""
    import resource
    resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
    resource.setrlimit(resource.RLIMIT_MEMLOCK, (0, 0))


def test_realtime_refused_is_one_line_and_the_run_goes_on(component: tuple[list[str], str]) -> None:
    cmd, name = component
    prefix: list[str] = []
    if os.geteuid() == 0:  # root: drop CAP_SYS_NICE and CAP_IPC_LOCK across the exec
        # util-linux (Essential on Debian) has it: without it the test cannot drop them.
        assert shutil.which("setpriv"), "setpriv (util-linux) is needed to drop root's capabilities"
        prefix = ["setpriv", "--inh-caps=-all", "--bounding-set=-sys_nice,-ipc_lock"]
    r = subprocess.run([*prefix, *cmd, "--realtime=7", "--clock", "virtual"], capture_output=True,
                       text=True, timeout=60, stdin=subprocess.DEVNULL, preexec_fn=_unprivileged)
    assert r.returncode == 0, r.stderr
    assert r.stderr == (
        f"{name}: warning: --realtime: refused SCHED_FIFO priority 7 (Operation not permitted) "
        "and locked memory (Operation not permitted); running on without them; to allow, "
        "raise `ulimit -r 7 -l unlimited` or grant cap_sys_nice,cap_ipc_lock (setcap), "
        "or run as root\n")


def build_with_a_drone(tmp_path: Path, name: str, url: str) -> None:
    """The Python model NAME with a MAVLink interface at ``url``, built into tmp_path/c."""
    model = tmp_path / f"{name}.yaml"
    model.write_text(MODEL.format(suffix="", lang="python").replace("name: flags", f"name: {name}")
                     .replace("parameters:", "interfaces:\n  drone: {type: mavlink, url: "
                              f"\"{url}\"}}\nparameters:"))
    r = run([sys.executable, "-m", "hfsmc", "build", str(model), "-o", str(tmp_path / "c")])
    assert r.returncode == 0, r.stderr


def test_missing_interface_library_is_reported_at_start(tmp_path: Path) -> None:
    """Without pymavlink the Python component stops at start, saying what to install
    (the C++ component's libraries are found by CMake at build time, docs/runtime.md)."""
    build_with_a_drone(tmp_path, "needs", "udpin:127.0.0.1:14550")
    # -I -S: no site-packages, so no pymavlink
    r = run([sys.executable, "-I", "-S", str(tmp_path / "c" / "needs.py"), "--clock", "virtual"])
    assert r.returncode == 1
    assert r.stderr == ("needs: error: cannot start: interface `drone` (mavlink) needs the Python "
                        "module `pymavlink`, which is not installed: pip install pymavlink\n")


def test_a_url_the_driver_refuses_stops_at_start_without_traceback(tmp_path: Path) -> None:
    pytest.importorskip("pymavlink")
    build_with_a_drone(tmp_path, "url", "udpin:127.0.0.1:99999")
    r = run([sys.executable, str(tmp_path / "c" / "url.py"), "--clock", "virtual"])
    assert r.returncode == 1
    assert r.stderr.startswith("url: error: cannot start: interface `drone` (mavlink): cannot "
                               "open `udpin:127.0.0.1:99999`: OverflowError"), r.stderr
    assert "Traceback" not in r.stderr
