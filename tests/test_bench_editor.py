"""bench/editor.py runs (issue 31's editor figures) in Debian's chromium, once, in its
short form; every figure is there and measured something. No time is asserted."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.support import needs_browser

ROOT = Path(__file__).resolve().parent.parent


@needs_browser
def test_editor_bench_short(tmp_path: Path) -> None:
    out = tmp_path / "results.json"
    p = subprocess.run([sys.executable, str(ROOT / "bench" / "editor.py"), "--keys", "4",
                        "--opens", "1", "--big", "600", "--saves", "1", "--json", str(out)],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-3000:] + p.stdout[-3000:]
    assert "keystroke -> gutter" in p.stdout
    fig = json.loads(out.read_text())["editor"]
    assert set(fig["open"]) == {"follow_colors", "states_500"}
    assert fig["open"]["states_500"]["states"] == 500
    assert fig["open"]["follow_colors"]["states"] > 10
    for o in fig["open"].values():
        assert 0 < o["best_ms"] <= o["median_ms"] and o["n"] == 1
    k = fig["keystroke_follow_colors"]
    assert k["total"]["n"] == k["after_debounce"]["n"] == 4
    assert 0 < k["after_debounce"]["p50_ms"] < k["total"]["p50_ms"]  # the debounce is before
    s = fig["save"]["states_600"]
    assert s["states"] == 600 and s["best_ms"] > 0
    assert isinstance(fig["met"], bool) and "revision" in fig
