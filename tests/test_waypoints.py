"""examples/waypoints flown end to end on both simulated autopilots, in lockstep: the
component and `hfsmc sim` as real processes on 127.0.0.1, the simulator the component's
clock (--lockstep, --clock sim). Lat/lon waypoints uploaded with the MISSION_ITEM_INT
protocol, flown in AUTO, landing at home (docs/interfaces.md, "Missions")."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.support import HFSMC, free_port

pytestmark = pytest.mark.timeout(400)
MODEL = ROOT / "examples" / "waypoints" / "waypoints.yaml"


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_waypoints_are_flown_in_auto_and_the_vehicle_lands_at_home(tmp_path: Path,
                                                                   autopilot: str) -> None:
    r = subprocess.run([*HFSMC, "build", str(MODEL), "-o", str(tmp_path / "component")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    udp, step = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    (tmp_path / "config.yaml").write_text(json.dumps(
        {"interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"}}}))
    extra = ["--autopilot", "px4", "--source-port", "0"] if autopilot == "px4" else []
    with (tmp_path / "sim.log").open("wb") as sim_log, \
            (tmp_path / "component.log").open("wb") as comp_log:
        sim = subprocess.Popen([*HFSMC, "sim", "--no-camera", "--mavlink",
                                f"udpout:127.0.0.1:{udp}", "--lockstep", str(step),
                                "--truth", str(tmp_path / "truth.json"), *extra],
                               stdout=sim_log, stderr=subprocess.STDOUT,
                               stdin=subprocess.DEVNULL)
        component = subprocess.Popen(
            [sys.executable, str(tmp_path / "component" / "waypoints.py"), "--config",
             str(tmp_path / "config.yaml"), "--trace", str(tmp_path / "trace.jsonl"),
             "--until", "400s", "--clock", f"sim:{step}", "--record",
             str(tmp_path / "flight.mcap")],
            stdout=comp_log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        try:
            component.wait(timeout=360)
        finally:
            for p in (component, sim):
                if p.poll() is None:
                    p.kill()
                p.wait(timeout=20)
    log = (tmp_path / "component.log").read_text()
    trace = [json.loads(line) for line in (tmp_path / "trace.jsonl").read_text().splitlines()
             if line.endswith("}")]
    entered = [r["state"] for r in trace if r["ev"] == "enter"]
    assert component.returncode == 0, log[-3000:]
    assert "Upload" in entered and "Fly" in entered and entered[-1] == "Done", log[-3000:]
    assert "Land" not in entered, log[-3000:]
    for n in (1, 2, 3):
        assert f"waypoint {n} of 3 reached" in log, log[-3000:]
    assert "drone: upload_mission accepted" in log
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["armed"] is False and truth["landed"] is True
    landing = truth["landing"]
    assert abs(landing["north"]) < 1.0 and abs(landing["east"]) < 1.0, truth
    assert truth["track"]["max_altitude"] > 9.5
    # recorded: the upload, its answer and the progress replay without the simulator
    r = subprocess.run([*HFSMC, "replay", str(tmp_path / "flight.mcap"), "--model", str(MODEL)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "(python -> python): identical" in r.stdout, r.stdout + r.stderr
