"""A Python component with a ros2 interface recorded against the simulated ground robot
(`hfsmc sim --robot diffdrive`, real DDS on loopback), then `hfsmc replay` of the
recording: identical (the same trace, the same publishes byte for byte); a model that
publishes other bytes is found at its first publish; the recording's topics decode with
mcap-ros2-support and export to a rosbag2."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.ros2_support import ros2_domain
from tests.support import ROOT

EXAMPLE = ROOT / "examples" / "stop_at_wall"


def _hfsmc(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hfsmc", *args], capture_output=True,
                          text=True, timeout=300, check=False, cwd=cwd)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(the model's copy, run.mcap): stop_at_wall driven to its wall and recorded."""
    tmp = tmp_path_factory.mktemp("ros2replay")
    model = tmp / "model"
    shutil.copytree(EXAMPLE, model)
    built = _hfsmc("build", str(model / "stop_at_wall.yaml"), "-o", str(tmp / "out"))
    assert built.returncode == 0, built.stderr
    mcap = tmp / "run.mcap"
    with ros2_domain() as dom:
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                                "--world", str(model / "world.yaml"), "--domain", str(dom)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            run = subprocess.run([sys.executable, str(tmp / "out" / "stop_at_wall.py"),
                                  "--record", str(mcap), "--until", "40s"],
                                 capture_output=True, text=True, timeout=90, check=False,
                                 env={"ROS_DOMAIN_ID": str(dom), "PATH": "/usr/bin:/bin",
                                      "CYCLONEDDS_URI": os.environ["CYCLONEDDS_URI"]})
        finally:
            sim.send_signal(signal.SIGINT)
            sim.communicate(timeout=30)
    assert run.returncode == 0, run.stderr
    assert "stopped (final)" in run.stderr
    return model, mcap


def test_replay_is_identical(recording: tuple[Path, Path]) -> None:
    model, mcap = recording
    done = _hfsmc("replay", str(mcap), "--model", str(model / "stop_at_wall.yaml"))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "(python -> python): identical:" in done.stdout
    commands = int(done.stdout.split(" commands")[0].rsplit(" ", 1)[1])
    assert commands > 10  # the publishes, each compared with its bytes


def test_replay_of_a_model_that_publishes_other_bytes(recording: tuple[Path, Path],
                                                      tmp_path: Path) -> None:
    model, mcap = recording
    changed = tmp_path / "changed"
    shutil.copytree(model, changed)
    text = (changed / "stop_at_wall.yaml").read_text()
    (changed / "stop_at_wall.yaml").write_text(
        text.replace("Twist(linear=Vector3(x=speed))", "Twist(linear=Vector3(x=speed * 0.99))"))
    done = _hfsmc("replay", str(mcap), "--model", str(changed / "stop_at_wall.yaml"))
    assert done.returncode == 1, done.stdout + done.stderr
    assert "different" in done.stdout and "(command 1):" in done.stdout
    assert 'recorded: robot.publish("cmd_vel", Twist(linear.x=0.4)) at ' in done.stdout
    assert 'now:      robot.publish("cmd_vel", Twist(linear.x=0.396)) at ' in done.stdout


def test_recorded_topics_decode_and_export(recording: tuple[Path, Path], tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import Reader

    _, mcap = recording
    with mcap.open("rb") as f:
        topics: dict[str, list[object]] = {}
        for _, ch, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages(topics=["/scan", "/odom", "/cmd_vel"]):
            topics.setdefault(ch.topic, []).append(msg)
    assert set(topics) == {"/scan", "/odom", "/cmd_vel"}
    assert all(len(s.ranges) > 10 for s in topics["/scan"])  # type: ignore[attr-defined]
    assert topics["/cmd_vel"][0].linear.x == pytest.approx(0.4)  # type: ignore[attr-defined]
    assert topics["/cmd_vel"][-1].linear.x == 0.0  # type: ignore[attr-defined]  # Stop's Twist()
    done = _hfsmc("export", "rosbag", str(mcap), str(tmp_path / "bag"))
    assert done.returncode == 0, done.stderr
    with Reader(tmp_path / "bag") as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts == {k: len(v) for k, v in topics.items()}
