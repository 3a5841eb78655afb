"""`hfsmc lsp` and the edit engine: keystroke to diagnostics, rename, the server's memory.

Everything goes through the real server over stdio, driven by pygls's client, with
the debounce set to 0 (``HFSMC_LSP_DEBOUNCE_MS=0``): a figure is the time from the
client sending ``didChange`` (one character typed in a `when` condition) to the
client receiving the matching ``publishDiagnostics``.  Rename is the time of the
``textDocument/rename`` request, once the editor's first ``documentSymbol`` request (timed
too) has had the tree and the index built.  The server's memory is its peak resident set
(VmHWM) after it has checked the 10,000-state model and renamed in it.  ``hfsmc
check``'s own wall time on the same files is measured in the same run, as a
reference (it includes starting Python).

    python bench/edit.py [--json bench/results.json] [--keys 200]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from frontend import generate  # bench/frontend.py: the synthetic models
from lsprotocol import types
from pygls.lsp.client import LanguageClient
from report import hfsmc_revision, loadavg, merge_json, table  # bench/report.py, beside this script

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "examples" / "follow_colors" / "follow_colors.yaml"
TARGETS = {"follow_colors_p99_ms": 50.0, "states_1000_p99_ms": 250.0, "rename_10000_ms": 1000.0}


class Bench:
    def __init__(self) -> None:
        self.client = LanguageClient("bench", "1")
        self.waiting: dict[str, asyncio.Future[list[types.Diagnostic]]] = {}

        @self.client.feature(types.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)  # type: ignore[untyped-decorator]
        def diagnostics(params: types.PublishDiagnosticsParams) -> None:
            fut = self.waiting.pop(params.uri, None)
            if fut is not None and not fut.done():
                fut.set_result(list(params.diagnostics))

        @self.client.feature(types.WINDOW_SHOW_MESSAGE)  # type: ignore[untyped-decorator]
        def message(params: types.ShowMessageParams) -> None:
            pass

    async def start(self) -> None:
        env = {**os.environ, "HFSMC_LSP_DEBOUNCE_MS": "0"}
        await self.client.start_io(sys.executable, "-m", "hfsmc", "lsp", env=env)
        await self.client.initialize_async(types.InitializeParams(
            capabilities=types.ClientCapabilities(), root_uri=ROOT.as_uri()))
        self.client.initialized(types.InitializedParams())

    @property
    def pid(self) -> int:
        server = self.client._server  # the subprocess pygls started
        assert server is not None
        return int(server.pid)

    def expect(self, uri: str) -> asyncio.Future[list[types.Diagnostic]]:
        fut: asyncio.Future[list[types.Diagnostic]] = asyncio.get_running_loop().create_future()
        self.waiting[uri] = fut
        return fut

    async def open(self, path: Path, text: str) -> str:
        uri = path.resolve().as_uri()
        fut = self.expect(uri)
        self.client.text_document_did_open(types.DidOpenTextDocumentParams(
            types.TextDocumentItem(uri, "yaml", 1, text)))
        await asyncio.wait_for(fut, 600)
        return uri

    async def keystrokes(self, uri: str, text: str, where: str, n: int) -> list[float]:
        """Type ``n`` characters (then delete them) after ``where``: ms to diagnostics."""
        at = text.index(where) + len(where)
        line = text.count("\n", 0, at)
        col = at - (text.rfind("\n", 0, at) + 1)
        times: list[float] = []
        version = 1
        for i in range(n):
            version += 1
            typing = i % 2 == 0
            change = types.TextDocumentContentChangePartial(
                range=types.Range(types.Position(line, col), types.Position(line, col if typing else col + 1)),
                text=" " if typing else "")
            fut = self.expect(uri)
            t0 = time.perf_counter()
            self.client.text_document_did_change(types.DidChangeTextDocumentParams(
                types.VersionedTextDocumentIdentifier(version=version, uri=uri), [change]))
            await asyncio.wait_for(fut, 600)
            times.append((time.perf_counter() - t0) * 1000)
        return times

    async def rename(self, uri: str, text: str, where: str, new: str) -> tuple[float, int]:
        """Rename the state whose key ``where`` (a line start and the key) shows."""
        at = text.index(where) + len(where) - len(where.lstrip())
        line = text.count("\n", 0, at)
        col = at - (text.rfind("\n", 0, at) + 1)
        t0 = time.perf_counter()
        edit = await self.client.text_document_rename_async(types.RenameParams(
            types.TextDocumentIdentifier(uri), types.Position(line, col), new))
        ms = (time.perf_counter() - t0) * 1000
        assert edit is not None and edit.changes is not None
        return ms, len(edit.changes[uri])

    async def stop(self) -> None:
        await self.client.shutdown_async(None)
        self.client.exit(None)
        await self.client.stop()  # type: ignore[no-untyped-call]


def peak_rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def check_ms(path: Path, runs: int = 3) -> float:
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "hfsmc", "check", "--no-cxx", str(path)],
                       capture_output=True, timeout=600)
        best = min(best, (time.perf_counter() - t0) * 1000)
    return best


def p99(xs: list[float]) -> float:
    return sorted(xs)[max(0, int(len(xs) * 0.99 + 0.5) - 1)]


async def run(keys: int, work: Path) -> dict[str, Any]:
    m1000 = work / "bench_1000.yaml"
    m1000.write_text(generate(1000)[0])
    m10000 = work / "bench_10000.yaml"
    m10000.write_text(generate(10000)[0])
    figures: dict[str, Any] = {}
    b = Bench()
    await b.start()
    try:
        text = FOLLOW.read_text()
        uri = await b.open(FOLLOW, text)
        t = await b.keystrokes(uri, text, "when: elapsed() > settle", keys)
        figures["follow_colors"] = {"p50_ms": statistics.median(t), "p99_ms": p99(t), "n": len(t)}
        text = m1000.read_text()
        uri = await b.open(m1000, text)
        t = await b.keystrokes(uri, text, "when: count >= limit", max(20, keys // 10))
        figures["states_1000"] = {"p50_ms": statistics.median(t), "p99_ms": p99(t), "n": len(t)}
        text = m10000.read_text()
        t0 = time.perf_counter()
        uri = await b.open(m10000, text)
        figures["states_10000_open_ms"] = (time.perf_counter() - t0) * 1000
        # an editor asks for the symbols on open: the tree and the index are built then
        t0 = time.perf_counter()
        await b.client.text_document_document_symbol_async(types.DocumentSymbolParams(
            types.TextDocumentIdentifier(uri)))
        figures["states_10000_symbols_ms"] = (time.perf_counter() - t0) * 1000
        ms, n = await b.rename(uri, text, "\n  R1:", "Renamed")
        figures["rename_10000"] = {"ms": ms, "edits": n}
        figures["server_peak_rss_mib_10000"] = peak_rss_mib(b.pid)
    finally:
        await b.stop()
    figures["check_ms"] = {"follow_colors": check_ms(FOLLOW), "states_1000": check_ms(m1000),
                           "states_10000": check_ms(m10000, 1)}
    return figures


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", type=Path)
    ap.add_argument("--keys", type=int, default=200, help="keystrokes on follow_colors")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="hfsmc-bench-edit-") as d:
        f = asyncio.run(run(args.keys, Path(d)))
    rows = [
        ["keystroke -> diagnostics, follow_colors", f"{f['follow_colors']['p50_ms']:.1f} ms",
         f"{f['follow_colors']['p99_ms']:.1f} ms", "p99 <= 50 ms", f"{f['check_ms']['follow_colors']:.0f} ms"],
        ["keystroke -> diagnostics, 1,000 states", f"{f['states_1000']['p50_ms']:.1f} ms",
         f"{f['states_1000']['p99_ms']:.1f} ms", "p99 <= 250 ms", f"{f['check_ms']['states_1000']:.0f} ms"],
        ["rename a state, 10,000 states", "", f"{f['rename_10000']['ms']:.0f} ms", "<= 1 s",
         f"{f['check_ms']['states_10000']:.0f} ms"],
        ["open -> diagnostics, 10,000 states", "", f"{f['states_10000_open_ms']:.0f} ms", "", ""],
        ["first symbols (tree + index), 10,000 states", "", f"{f['states_10000_symbols_ms']:.0f} ms", "", ""],
        ["server peak RSS, 10,000 states", "", f"{f['server_peak_rss_mib_10000']:.0f} MiB", "", ""],
    ]
    for line in table(rows, ["measure", "p50", "p99 / value", "target", "hfsmc check"]):
        print(line)
    ok = (f["follow_colors"]["p99_ms"] <= TARGETS["follow_colors_p99_ms"]
          and f["states_1000"]["p99_ms"] <= TARGETS["states_1000_p99_ms"]
          and f["rename_10000"]["ms"] <= TARGETS["rename_10000_ms"])
    print("targets met" if ok else "targets NOT met")
    if args.json:
        merge_json(args.json, "edit", {**f, "targets": TARGETS, "met": ok, "loadavg": loadavg(),
                                       "revision": hfsmc_revision()})


if __name__ == "__main__":
    main()
