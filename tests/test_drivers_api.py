"""The interfaces' methods are described once, by the Python drivers (hfsmc/drivers.py reads
them): what `hfsmc check` knows must be what the drivers have, and the C++ headers, the
docs' tables, the scenario files and the playback's test doubles must agree with it."""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path
from types import ModuleType
from typing import Any, ClassVar

import pytest

from hfsmc.drivers import (
    ATTRIBUTES,
    CPP_NAMES,
    SOURCES,
    DeclarationError,
    disagreement,
    driver,
    read_cpp_driver,
)
from hfsmc.scenario import acknowledged, commands_of
from tests.conftest import ROOT

TEMPLATES = ROOT / "templates"
KINDS = sorted(SOURCES)


def _module(kind: str) -> ModuleType:
    return importlib.import_module(f"hfsmc.templates.python.{SOURCES[kind][0][:-3]}")


@pytest.mark.parametrize("kind", KINDS)
def test_check_knows_every_public_method_of_the_imported_driver(kind: str) -> None:
    """The ast reading against the classes Python itself builds: same names, same parameters
    (a method added, renamed or given another parameter shows here)."""
    module = _module(kind)
    _, queries, live = SOURCES[kind]
    # a driver built on the driver base (hfsmc_driver.Driver): the base's runtime methods
    # are not the interface's, except those it gives snippets too (PUBLIC)
    base = next((c for c in getattr(module, live).__mro__ if c.__name__ == "Driver"), None)
    runtime = set() if base is None else set(vars(base)) - set(getattr(module, queries).PUBLIC)
    found = {}
    for cls in (getattr(module, queries), getattr(module, live)):
        for name, fn in inspect.getmembers(cls, inspect.isfunction):
            if not name.startswith("_") and name not in runtime:
                found[name] = tuple(inspect.signature(fn).parameters)[1:]
    d = driver(kind)
    assert d is not None
    assert {m.name: m.params for m in d.methods.values()} == found
    for m in d.methods.values():
        params = inspect.signature(getattr(getattr(module, live), m.name)).parameters.values()
        assert m.required == sum(p.default is inspect.Parameter.empty for p in params) - 1


def test_commands_are_what_the_scenarios_expect_and_script() -> None:
    assert commands_of("mavlink") == ("set_mode", "arm", "disarm", "takeoff", "land", "rtl",
                                      "hold", "set_velocity", "goto", "goto_location",
                                      "set_yaw", "upload_mission", "upload_fence",
                                      "enable_fence")
    assert acknowledged("mavlink") == ("set_mode", "arm", "disarm", "takeoff", "land", "rtl",
                                       "upload_mission", "upload_fence", "enable_fence")
    assert commands_of("camera") == () and commands_of("ros_topic") == ()
    # the docs' list of last_ack's commands is the driver's
    text = (ROOT / "docs/interfaces.md").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| `last_ack(command)`"))
    assert re.findall(r"`(\w+)`", row.split("the last outcome of ")[1].split(":")[0]) == \
        ["arm", "disarm", "takeoff", "land", "rtl", "set_mode", "upload_mission",
         "upload_fence", "enable_fence"]


@pytest.mark.parametrize("kind", KINDS)
def test_the_cpp_header_declares_the_same_methods(kind: str) -> None:
    d = driver(kind)
    assert d is not None
    header = (TEMPLATES / "cpp/hfsmc" / f"{kind}.hpp").read_text()
    cls = {"mavlink": "Mavlink", "camera": "Camera"}[kind]
    body = header[header.index(f"class {cls} ") :]
    body = body[: body.index("\n};")]
    public = body.split("private:")[0]
    if re.search(rf"class {cls} : public Driver<", header):  # and what its base offers
        base = (TEMPLATES / "cpp/hfsmc/driver.hpp").read_text()
        base = base[base.index("class Driver : ") :]
        public += re.split(r"\n *(?:private|protected):", base[: base.index("\n};")])[0]
    for m in (*d.methods.values(),):
        name = CPP_NAMES.get(m.name, m.name)
        decl = re.search(rf"\b{name}\(([^)]*)\)", public)
        assert decl is not None, f"{cls} has no public {name}()"
        count = 0 if not decl.group(1).strip() else decl.group(1).count(",") + 1
        assert count == len(m.params), (name, decl.group(0))
    for attr in ATTRIBUTES:  # C++: methods
        assert re.search(rf"\b{attr}\(\)", header), attr


@pytest.mark.parametrize("kind", KINDS)
def test_each_builtin_is_declared_as_a_user_driver_is_in_both_languages(kind: str) -> None:
    """Every built-in driver passes the one seam of docs/drivers.md: its Python class
    derives from the driver base and marks its methods, and the C++ header's declaration
    block agrees with it (as a user's twin drivers must, E189)."""
    file, cls, live = SOURCES[kind]
    d = driver(kind)
    assert d is not None and d.cls == cls and d.type == kind
    expected = {"mavlink": (["rate", "ack_timeout", "source_system", "autopilot"],
                            ("fence_breached", False)),
                "camera": (["size"], ("count", 0))}[kind]
    assert [k for k, _ in d.options] == expected[0] and expected[1] in d.snapshot
    header = (TEMPLATES / f"cpp/hfsmc/{kind}.hpp").read_text()
    cpp = read_cpp_driver(header, kind)
    assert cpp.cls == {"mavlink": "Mavlink", "camera": "Camera"}[kind]
    assert disagreement(d, cpp) is None
    with pytest.raises(DeclarationError, match="not a built-in type"):  # a user's may not
        read_cpp_driver(header)
    sys.path.insert(0, str(TEMPLATES / "python"))
    try:
        module = importlib.import_module(file[:-3])
        base = importlib.import_module("hfsmc_driver")
    finally:
        sys.path.remove(str(TEMPLATES / "python"))
    assert issubclass(getattr(module, live), base.Driver)
    queries = getattr(module, cls)
    assert queries.SNAPSHOT.keys() == dict(d.snapshot).keys()
    for m in d.methods.values():  # marked as a user driver's methods are, but the PUBLIC
        fn = getattr(queries, m.name)
        mark = None if m.name in queries.PUBLIC else "command" if m.command else "query"
        assert getattr(fn, "hfsmc_kind", None) == mark, m.name
        assert getattr(fn, "hfsmc_ack", False) == m.acknowledged, m.name


@pytest.mark.parametrize("kind", KINDS)
def test_the_docs_table_lists_every_method(kind: str) -> None:
    d = driver(kind)
    assert d is not None
    text = (ROOT / "docs/interfaces.md").read_text()
    section = text[text.index(f"## `{kind}`") :]
    section = section[: section.index("\n## ", 3)] if "\n## " in section[3:] else section
    rows = set(re.findall(r"^\| `(\w+)\(([^)]*)\)`", section, re.M))
    assert {(m.name, ", ".join(m.params)) for m in d.methods.values()} == rows


@pytest.mark.parametrize("kind", KINDS)
def test_the_playback_doubles_answer_every_method_and_name_the_interface(
        kind: str, tmp_path: Path) -> None:
    """hfsmc test's test doubles (hfsmc_playback.py) have every method, and a method the
    interface lacks is said with the interface's name, not the double's class."""
    sys.path.insert(0, str(TEMPLATES / "python"))
    try:
        module = importlib.import_module(SOURCES[kind][0][:-3])
        fake = getattr(module, SOURCES[kind][1]).fake("drone" if kind == "mavlink" else "cam",
                                                      None, {}, None)  # the driver's own
    finally:
        sys.path.remove(str(TEMPLATES / "python"))
    d = driver(kind)
    assert d is not None
    for m in d.methods.values():
        assert callable(getattr(fake, m.name)), m.name
    with pytest.raises(AttributeError) as e:
        fake.fly_to(1, 2, 3)
    name = "drone" if kind == "mavlink" else "cam"
    assert str(e.value).startswith(f"the {kind} interface `{name}` has no method or attribute "
                                   "`fly_to`")
    assert "Fake" not in str(e.value)


_HOOKED = '''
from hfsmc_driver import Driver, command, query


class Gadget(Driver):
    KIND = "gadget"
    SNAPSHOT = {"distance": float("inf"), "acks": ""}
    OPTIONS = {"stale": 1.0}
    PUBLIC = ("close",)

    @query(reads="distance")
    def distance(self):
        return self.value("distance")

    @command(checked=True, ack=True)
    def beep(self, ms):
        if ms <= 0:
            raise ValueError("ms > 0")
        self.tell("beep", [int(ms)])
        self.sent = int(ms)
'''


def test_the_bases_hooks_are_declared_checked_and_run(tmp_path: Path) -> None:
    """The hooks mavlink uses, on a user's driver: read from the declaration (a wrong one at
    its line), and at run time: a checked command tells what it checked and runs in a
    fake too; a query that reads one field is answered when the script lacks another."""
    from hfsmc.drivers import read_python_driver

    d = read_python_driver(_HOOKED)
    assert [(m.name, m.command, m.acknowledged) for m in d.methods.values()] == [
        ("distance", False, False), ("beep", True, True), ("close", False, False)]
    for wrong, said in (('reads="distance"', 'reads="far"'), ("ack=True", "ack=1"),
                        ('PUBLIC = ("close",)', 'PUBLIC = ("open",)'),
                        ("checked=True", "checked=True, sends=1")):
        with pytest.raises(DeclarationError) as e:
            read_python_driver(_HOOKED.replace(wrong, said))
        assert e.value.line > 1, e.value.message
    sys.path.insert(0, str(TEMPLATES / "python"))
    try:
        module = tmp_path / "gadget_hooked.py"
        module.write_text(_HOOKED)
        sys.path.insert(0, str(tmp_path))
        cls = importlib.import_module("gadget_hooked").Gadget
    finally:
        sys.path[:] = [p for p in sys.path if p not in (str(tmp_path), str(TEMPLATES / "python"))]

    asked: list[tuple[object, ...]] = []

    class Playback:  # what a fake tells the playback of a query it cannot answer
        def asked(self, *what: object) -> None:
            asked.append(what[:3])

    told: list[tuple[str, list[object]]] = []
    fake = cls.fake("g", None, {}, Playback())
    fake.on_command = lambda call, args: told.append((call, args))
    fake.beep(2.7)  # checked, told as converted, run in the fake (it sends nothing itself)
    assert told == [("beep", [2])] and fake.sent == 2
    with pytest.raises(ValueError):
        fake.beep(0)
    assert told == [("beep", [2])]  # a refused command is not told
    fake.lacks = frozenset({"acks"})  # the recording lacks another field: answered
    assert fake.distance() == float("inf") and asked == []
    fake.lacks = frozenset({"distance"})
    fake.distance()
    assert asked == [("g", "distance", "distance")]
def test_the_driver_base_gives_every_driver_the_cameras_hooks(capsys: pytest.CaptureFixture[str]) -> None:
    """Images beside the snapshot (each told to the recording once) and a reader that
    reconnects saying each change once: the base's, not the camera's own."""
    base: Any = importlib.import_module("hfsmc.templates.python.hfsmc_driver")

    class Pictures(base.Driver):  # type: ignore[misc]
        KIND = "pictures"
        SNAPSHOT: ClassVar[dict[str, Any]] = {"n": 0}
        FRAMES = "n"

        @base.query(reads="frame")  # type: ignore[untyped-decorator]
        def picture(self) -> Any:
            return self.image()

    d = Pictures("pics", None, {})
    told: list[int] = []
    d.on_frame = lambda n, image, encoded: told.append(n)
    assert d.picture() is None and told == []
    for n in (1, 1, 2):
        d.hold_image(f"image {n}")
        d.read = lambda n=n: {"n": n}
        d.snapshot()
        assert d.picture() == f"image {n}" and d.picture() == f"image {n}"
    assert told == [1, 2] and d._last_seen() == "image 2"
    tries = iter([False, False, True, False])

    def attempt() -> bool:
        got = next(tries, None)
        if got is None:  # nothing left to try: the driver closes
            d._stop.set()
            return False
        if got:
            d.tell_up("back")
        return got

    d.RECONNECT_MIN_S = d.RECONNECT_MAX_S = 0.0
    d.keep_connected(attempt, lambda got: "lost" if got else "not available")
    assert capsys.readouterr().err.splitlines() == ["pics: not available", "pics: back",
                                                    "pics: lost"]
