"""Property: any valid model gives a Python component that compiles, runs and traces well."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import jsonschema
from hypothesis import HealthCheck, given, settings

from hfsmc.component import write_component
from hfsmc.pipeline import compile_file
from tests.conftest import ROOT
from tests.test_roundtrip import dump_yaml, models

VALIDATOR = jsonschema.Draft202012Validator(
    json.loads((ROOT / "schemas/trace.schema.json").read_text()))


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(models())
def test_any_valid_model_builds_and_runs(data: dict[str, Any]) -> None:
    result = compile_file("m.yaml", text=dump_yaml(data))
    assert result.model is not None, result.diagnostics
    with tempfile.TemporaryDirectory() as tmp:
        built = write_component(result.model, "python", Path(tmp) / "c")
        compile(built.main.read_text(), str(built.main), "exec")
        run = subprocess.run([sys.executable, "-I", "-S", str(built.main), "--clock", "virtual",
                              "--until", "2s", "--trace", "-"], capture_output=True, text=True,
                             timeout=60, stdin=subprocess.DEVNULL)
    assert run.returncode == 0, run.stderr
    assert "Traceback (most recent call last):" not in run.stderr
    records = [json.loads(line) for line in run.stdout.splitlines()]
    kinds: dict[tuple[str, ...], dict[str, Any]] = {}  # one record of each shape is enough
    for rec in records:
        kinds.setdefault((rec["ev"], *rec), rec)
    for rec in kinds.values():
        VALIDATOR.validate(rec)
    assert records[0] == {"t": 0, "ev": "start", "name": data["name"]}
    assert records[-1]["ev"] == "stop" and records[-1]["reason"] in ("until", "final")
    assert [r["t"] for r in records] == sorted(r["t"] for r in records)
    # Every state entered is exited before the stop, innermost first, and vice versa.
    open_states: list[str] = []
    for rec in records:
        if rec["ev"] == "enter":
            open_states.append(rec["state"])
        elif rec["ev"] == "exit":
            assert open_states and open_states[-1] == rec["state"], (rec, open_states)
            open_states.pop()
    assert open_states == []
