"""`hfsmc lsp` through a real client over stdio (pytest-lsp): diagnostics equal to
`hfsmc check --format json`, definition, references, rename, completion, hover,
symbols, a code action applied, a document mid-typing, a file changed on disk."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
from pathlib import Path

import pytest
import pytest_lsp
from lsprotocol import types
from pytest_lsp import ClientServerConfig, LanguageClient, client_capabilities

from hfsmc.edit.text import TextEdit, apply_edits
from hfsmc.lsp.analysis import is_model
from hfsmc.lsp.positions import Lines
from tests.support import library_and_users

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "examples" / "follow_colors" / "follow_colors.yaml"
INVALID = ROOT / "tests" / "invalid"
pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest_lsp.fixture(config=ClientServerConfig(server_command=[sys.executable, "-m", "hfsmc", "lsp"],
                                              server_env={"HFSMC_LSP_DEBOUNCE_MS": "20"}),
                    scope="module")  # type: ignore[untyped-decorator]
async def client(lsp_client: LanguageClient):  # type: ignore[no-untyped-def]
    await lsp_client.initialize_session(types.InitializeParams(
        capabilities=client_capabilities("visual-studio-code"), root_uri=ROOT.as_uri()))
    yield
    await lsp_client.shutdown_session()


async def opened(client: LanguageClient, path: Path, text: str | None = None) -> str:
    uri = path.resolve().as_uri()
    client.diagnostics.pop(uri, None)
    client.text_document_did_open(types.DidOpenTextDocumentParams(types.TextDocumentItem(
        uri, "yaml", 1, path.read_text("utf-8") if text is None else text)))
    await published(client, uri)
    return uri


async def published(client: LanguageClient, uri: str) -> list[types.Diagnostic]:
    for _ in range(200):
        if uri in client.diagnostics:
            return list(client.diagnostics[uri])
        await asyncio.sleep(0.05)
    raise AssertionError(f"no diagnostics published for {uri}")


async def changed(client: LanguageClient, uri: str, version: int, text: str) -> list[types.Diagnostic]:
    client.diagnostics.pop(uri, None)
    client.text_document_did_change(types.DidChangeTextDocumentParams(
        types.VersionedTextDocumentIdentifier(version=version, uri=uri),
        [types.TextDocumentContentChangeWholeDocument(text)]))
    return await published(client, uri)


def closed(client: LanguageClient, uri: str) -> None:
    client.text_document_did_close(types.DidCloseTextDocumentParams(types.TextDocumentIdentifier(uri)))


def position(text: str, needle: str, nth: int = 0, delta: int = 1) -> types.Position:
    off = -1
    for _ in range(nth + 1):
        off = text.index(needle, off + 1)
    return Lines(text).position(off + delta)


def invalid_files() -> list[Path]:
    out = []
    for p in sorted(INVALID.iterdir()):
        if p.is_file() and p.name != "EXPECTED":
            raw = p.read_bytes()
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError:
                continue
            if "\x00" not in text:
                out.append(p)
    return out


async def test_diagnostics_equal_check_json_on_every_invalid_file(client: LanguageClient) -> None:
    files = invalid_files()
    run = subprocess.run([sys.executable, "-m", "hfsmc", "check", "--format", "json",
                          *map(str, files)], capture_output=True, text=True, timeout=600)
    expected: dict[str, list[tuple[str, int, int]]] = {}
    for d in json.loads(run.stdout)["diagnostics"] if run.stdout.startswith("{") else json.loads(run.stdout):
        f = str(Path(d["file"]).resolve())
        lines = Lines(Path(f).read_text("utf-8", errors="replace")) if Path(f).is_file() else Lines("")
        pos = lines.span_position(d["line"], d["col"])
        expected.setdefault(f, []).append((d["code"], pos.line, pos.character))
    non_ascii = 0
    for p in files:
        text = p.read_text("utf-8")
        uri = await opened(client, p)
        got = sorted((str(d.code), d.range.start.line, d.range.start.character)
                     for d in client.diagnostics[uri])
        if is_model(text):
            assert got == sorted(expected.get(str(p.resolve()), [])), p.name
            if any(any(ord(c) > 127 for c in Lines(text).line(line)) for _, line, _ in got):
                non_ascii += 1
        else:
            assert got == [], p.name  # not a model: left alone
        closed(client, uri)
    assert non_ascii >= 1  # a line with non-ASCII text was compared in UTF-16 columns


async def test_utf16_columns_after_non_bmp_text(client: LanguageClient, tmp_path: Path) -> None:
    text = ('hfsm: 1\nname: m\ninitial: A\nstates:\n  A:\n'
            '    transitions: [{name: "🚁 é", to: Nowhere, after: 1s}]\n')
    p = tmp_path / "u.yaml"
    p.write_text(text)
    uri = await opened(client, p)
    diags = client.diagnostics[uri]
    d = next(d for d in diags if "Nowhere" in d.message)
    # `Nowhere` is at character 36 of its line; the helicopter takes 2 UTF-16 units
    assert (d.range.start.line, d.range.start.character) == (5, 37)
    closed(client, uri)


async def test_definition_and_references_of_each_kind(client: LanguageClient) -> None:
    text = MODEL.read_text()
    uri = await opened(client, MODEL)
    doc = types.TextDocumentIdentifier(uri)
    lines = Lines(text)

    async def definition(pos: types.Position) -> types.Location:
        r = await client.text_document_definition_async(types.DefinitionParams(doc, pos))
        assert isinstance(r, types.Location), r
        return r

    # a state in `to`, in `initial`, in `on_interrupt`, in an active() path
    land = lines.position(text.index("  Land:\n") + 2)
    for needle in ("to: Land", "on_interrupt: Land"):
        loc = await definition(position(text, needle, delta=len(needle) - 1))
        assert loc.range.start == land
    loc = await definition(position(text, "initial: FollowGreen", delta=10))
    assert loc.range.start == lines.position(text.index("FollowGreen:"))
    # a path into a used file: the state in examples/lib/takeoff.yaml
    loc = await definition(position(text, 'active("TakeOff/Airborne")', delta=18))
    assert loc.uri.endswith("examples/lib/takeoff.yaml")
    lib = (ROOT / "examples" / "lib" / "takeoff.yaml").read_text()
    assert Lines(lib).line(loc.range.start.line).strip().startswith("Airborne")
    # a use file, a $NAME parameter, a variable, an interface
    loc = await definition(position(text, "use: ../lib/takeoff", delta=8))
    assert loc.uri.endswith("examples/lib/takeoff.yaml")
    loc = await definition(position(text, "$altitude", delta=3))
    assert loc.range.start == lines.position(text.index("  altitude:") + 2)
    loc = await definition(position(text, "stages.append", delta=2))
    assert loc.range.start == lines.position(text.index("  stages:") + 2)
    loc = await definition(position(text, "drone.hold()", delta=2))
    assert loc.range.start == lines.position(text.index("  drone:") + 2)

    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc, position=position(text, "  Land:\n", delta=3),
        context=types.ReferenceContext(include_declaration=False)))
    assert refs is not None
    assert len(refs) == text.count("to: Land") + 1  # and on_interrupt
    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc, position=position(text, "  stages:", delta=3),
        context=types.ReferenceContext(include_declaration=True)))
    assert refs is not None and len(refs) == 6  # the key, 3 uses in functions, 2 in on_shutdown
    closed(client, uri)


async def test_rename_across_the_model(client: LanguageClient) -> None:
    text = MODEL.read_text()
    uri = await opened(client, MODEL)
    edit = await client.text_document_rename_async(types.RenameParams(
        types.TextDocumentIdentifier(uri), position(text, "  Mission:", delta=3), "Flight"))
    assert edit is not None and edit.changes is not None
    lines = Lines(text)
    edits = [TextEdit(lines.offset(e.range.start), lines.offset(e.range.end), e.new_text)
             for e in edit.changes[uri]]
    new = apply_edits(text, edits)
    assert "Mission" not in new.replace("mission", "") and new.count("Flight") == 3
    closed(client, uri)


async def test_rename_of_a_used_files_state_is_refused(client: LanguageClient) -> None:
    text = MODEL.read_text()
    uri = await opened(client, MODEL)
    with pytest.raises(Exception, match="read-only here"):
        await client.text_document_rename_async(types.RenameParams(
            types.TextDocumentIdentifier(uri), position(text, "TakeOff/Airborne", delta=10), "Up"))
    closed(client, uri)


async def test_completion_lists(client: LanguageClient) -> None:
    text = MODEL.read_text()
    uri = await opened(client, MODEL)
    doc = types.TextDocumentIdentifier(uri)

    async def labels(text2: str, needle: str, version: int) -> set[str]:
        await changed(client, uri, version, text2)
        pos = position(text2, needle, delta=len(needle))
        r = await client.text_document_completion_async(types.CompletionParams(doc, pos))
        assert isinstance(r, types.CompletionList)
        return {i.label for i in r.items}

    t = text.replace("      - {name: landed, to: Done, when: done()}",
                     "      - {name: landed, to: Done, when: drone.}")
    assert {"land", "armed", "takeoff"} <= await labels(t, "when: drone.", 2)
    t = text.replace("  Done:\n    final: true", "  Done:\n    final: true\n    ")
    got = await labels(t, "Done:\n    final: true\n    ", 3)
    assert {"entry", "during", "transitions", "initial"} <= got and "final" not in got
    t = text.replace("{to: Done, after: 60s", "{to: Li, after: 60s")
    assert {"LinkLost", "Land", "Mission", "TakeOff", "Done"} <= await labels(t, "{to: Li", 4)
    t = text.replace('active("TakeOff/Airborne")', 'active("Mis')
    assert "Mission/FollowGreen/Track" in await labels(t, 'active("', 5)
    t = text.replace("with: {altitude: $altitude", "with: {altitude: $")
    assert "altitude" in await labels(t, "altitude: $", 6)
    closed(client, uri)


async def test_hover_key_and_diagnostic(client: LanguageClient, tmp_path: Path) -> None:
    text = MODEL.read_text()
    uri = await opened(client, MODEL)
    doc = types.TextDocumentIdentifier(uri)
    h = await client.text_document_hover_async(types.HoverParams(doc, position(text, "period: 50ms", delta=2)))
    assert h is not None and isinstance(h.contents, types.MarkupContent)
    assert "period" in h.contents.value and "Cycle" in h.contents.value
    closed(client, uri)
    bad = tmp_path / "b.yaml"
    bad.write_text("hfsm: 1\nname: m\ninitial: A\nstates:\n  A: {fnial: true}\n")
    uri = await opened(client, bad)
    h = await client.text_document_hover_async(types.HoverParams(types.TextDocumentIdentifier(uri),
                                                                 types.Position(4, 7)))
    assert h is not None and isinstance(h.contents, types.MarkupContent)
    assert "E100" in h.contents.value and "unknown key" in h.contents.value
    closed(client, uri)


async def test_symbols_are_the_state_tree(client: LanguageClient) -> None:
    uri = await opened(client, MODEL)
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(
        types.TextDocumentIdentifier(uri)))
    assert syms is not None
    top = [s.name for s in syms if isinstance(s, types.DocumentSymbol)]
    assert top == ["TakeOff", "Mission", "LinkLost", "Land", "Done"]
    mission = next(s for s in syms if isinstance(s, types.DocumentSymbol) and s.name == "Mission")
    assert mission.children is not None
    assert [c.name for c in mission.children][:2] == ["FollowGreen", "FollowBlue"]
    closed(client, uri)


async def test_code_action_did_you_mean_applied(client: LanguageClient, tmp_path: Path) -> None:
    text = "hfsm: 1\nname: m\ninitial: Idle\nstates:\n  Idle:\n    transitions: [{to: Dnoe, after: 1s}]\n  Done: {final: true}\n"
    p = tmp_path / "c.yaml"
    p.write_text(text)
    uri = await opened(client, p)
    diags = client.diagnostics[uri]
    target = [d for d in diags if d.data and "replace" in d.data]
    assert target, diags
    actions = await client.text_document_code_action_async(types.CodeActionParams(
        types.TextDocumentIdentifier(uri), target[0].range, types.CodeActionContext(target)))
    assert actions
    act = actions[0]
    assert isinstance(act, types.CodeAction) and act.edit is not None and act.edit.changes
    lines = Lines(text)
    fixed = apply_edits(text, [TextEdit(lines.offset(e.range.start), lines.offset(e.range.end), e.new_text)
                               for e in act.edit.changes[uri]])
    assert "{to: Done, after: 1s}" in fixed
    assert not [d for d in await changed(client, uri, 2, fixed) if d.severity == types.DiagnosticSeverity.Error]
    closed(client, uri)


async def test_code_action_quotes_a_value_with_a_colon(client: LanguageClient, tmp_path: Path) -> None:
    text = "hfsm: 1\nname: m\ndescription: go: now\ninitial: A\nstates:\n  A: {final: true}\n"
    p = tmp_path / "q.yaml"
    p.write_text(text)
    uri = await opened(client, p)
    target = [d for d in client.diagnostics[uri] if d.data and d.data.get("quote")]
    assert target
    actions = await client.text_document_code_action_async(types.CodeActionParams(
        types.TextDocumentIdentifier(uri), target[0].range, types.CodeActionContext(target)))
    assert actions and isinstance(actions[0], types.CodeAction) and actions[0].edit is not None
    assert actions[0].edit.changes is not None
    (e,) = actions[0].edit.changes[uri]
    assert e.new_text == '"go: now"'
    closed(client, uri)


async def test_syntax_error_mid_typing_keeps_the_last_good_symbols(client: LanguageClient) -> None:
    text = MODEL.read_text()
    uri = await opened(client, MODEL)
    broken = text.replace("  Done:\n    final: true", "  Done:\n    final: [true\n  X: {")
    diags = await changed(client, uri, 2, broken)
    assert any(d.code == "E002" for d in diags)
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(
        types.TextDocumentIdentifier(uri)))
    assert syms is not None and [s.name for s in syms if isinstance(s, types.DocumentSymbol)][-1] == "Done"
    assert not [d for d in await changed(client, uri, 3, text) if d.severity == types.DiagnosticSeverity.Error]
    closed(client, uri)


async def test_non_models_are_left_alone(client: LanguageClient, tmp_path: Path) -> None:
    p = tmp_path / "ci.yaml"
    p.write_text("jobs:\n  build: {runs-on: x\n")
    uri = await opened(client, p)
    assert not client.diagnostics[uri]
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(
        types.TextDocumentIdentifier(uri)))
    assert not syms
    closed(client, uri)


async def test_a_file_changed_on_disk_under_unsaved_edits_is_a_conflict(
        client: LanguageClient, tmp_path: Path) -> None:
    p = tmp_path / "d.yaml"
    text = "hfsm: 1\nname: m\ninitial: A\nstates:\n  A: {final: true}\n"
    p.write_text(text)
    uri = await opened(client, p)
    await changed(client, uri, 2, text + "# mine\n")
    p.write_text(text + "# theirs\n")
    client.messages.clear()
    await changed(client, uri, 3, text + "# mine, more\n")
    for _ in range(100):
        if client.messages:
            break
        await asyncio.sleep(0.05)
    assert any("changed on disk under unsaved edits" in m.message for m in client.messages)
    assert p.read_text().endswith("# theirs\n")  # the server never writes the file
    closed(client, uri)


XML = ROOT / "examples" / "traffic_light" / "traffic_light.xml"


async def test_xml_definition_references_rename_symbols(client: LanguageClient) -> None:
    text = XML.read_text()
    uri = await opened(client, XML)
    doc = types.TextDocumentIdentifier(uri)
    lines = Lines(text)
    amber = lines.position(text.index('name="Amber"') + 6)
    for needle in ('to="Amber"', 'initial="Green"'):
        loc = await client.text_document_definition_async(types.DefinitionParams(
            doc, position(text, needle, delta=len(needle) - 2)))
        assert isinstance(loc, types.Location)
        if "Amber" in needle:
            assert loc.range.start == amber
        else:
            assert loc.range.start == lines.position(text.index('name="Green"') + 6)
    loc = await client.text_document_definition_async(types.DefinitionParams(
        doc, position(text, "count >= cycles", delta=11)))
    assert isinstance(loc, types.Location)
    assert loc.range.start == lines.position(text.index('name="cycles"') + 6)
    refs = await client.text_document_references_async(types.ReferenceParams(
        text_document=doc, position=position(text, 'name="count"', delta=7),
        context=types.ReferenceContext(include_declaration=True)))
    assert refs is not None and len(refs) == 4  # the declaration, `count = count + 1`, the when
    edit = await client.text_document_rename_async(types.RenameParams(
        doc, position(text, 'name="Green"', delta=7), "Go"))
    assert edit is not None and edit.changes is not None
    new = apply_edits(text, [TextEdit(lines.offset(e.range.start), lines.offset(e.range.end),
                                      e.new_text) for e in edit.changes[uri]])
    assert new.count('"Go"') == 3 and '"Green"' not in new
    assert [x for x in new.splitlines() if x not in text.splitlines()] == [
        x.replace('"Green"', '"Go"') for x in text.splitlines() if '"Green"' in x]
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(doc))
    assert syms is not None
    assert [s.name for s in syms if isinstance(s, types.DocumentSymbol)] == ["Green", "Amber", "Red",
                                                                             "Night"]
    closed(client, uri)


async def test_xml_completion_hover_and_a_fix(client: LanguageClient, tmp_path: Path) -> None:
    text = XML.read_text()
    p = tmp_path / "light.xml"
    p.write_text(text)
    uri = await opened(client, p)
    doc = types.TextDocumentIdentifier(uri)

    async def labels(text2: str, needle: str, version: int) -> set[str]:
        await changed(client, uri, version, text2)
        r = await client.text_document_completion_async(types.CompletionParams(
            doc, position(text2, needle, delta=len(needle))))
        assert isinstance(r, types.CompletionList)
        return {i.label for i in r.items}

    t = text.replace('<transition to="Green" after="5s"/>', '<transition to="N" after="5s"/>')
    assert {"Night", "Green", "Amber", "Red"} <= await labels(t, '<transition to="', 2)
    t = text.replace('<transition to="Green" after="5s"/>', '<transition to="Green" ')
    assert await labels(t, '<transition to="Green" ', 3) == {"after", "name"}
    t = text.replace('<state name="Night" final="true"/>', '<state name="Night" final="true"><')
    assert {"entry", "transition", "automaton", "with"} <= await labels(t, 'final="true"><', 4)
    t = text.replace("<when>button</when>", '<when>active("Am</when>')
    assert "Amber" in await labels(t, 'active("Am', 5)
    t = text.replace("<when>button</when>", "<when>cou</when>")
    assert {"count", "cycles", "elapsed"} <= await labels(t, "<when>cou", 6)
    h = await client.text_document_hover_async(types.HoverParams(doc, position(text, 'period="100ms"')))
    assert h is not None and isinstance(h.contents, types.MarkupContent)
    assert "period" in h.contents.value and "Cycle" in h.contents.value
    # a misspelt target: the diagnostic, its hover, its quick fix applied
    bad = text.replace('<transition to="Green" after="5s"/>', '<transition to="Gren" after="5s"/>')
    diags = await changed(client, uri, 7, bad)
    target = [d for d in diags if d.data and d.data.get("replace") == "Green"]
    assert target, diags
    h = await client.text_document_hover_async(types.HoverParams(doc, target[0].range.start))
    assert h is not None and isinstance(h.contents, types.MarkupContent)
    assert str(target[0].code) in h.contents.value
    actions = await client.text_document_code_action_async(types.CodeActionParams(
        doc, target[0].range, types.CodeActionContext(target)))
    assert actions and isinstance(actions[0], types.CodeAction) and actions[0].edit is not None
    assert actions[0].edit.changes is not None
    lines = Lines(bad)
    fixed = apply_edits(bad, [TextEdit(lines.offset(e.range.start), lines.offset(e.range.end), e.new_text)
                              for e in actions[0].edit.changes[uri]])
    assert fixed == text
    # mid-typing: a broken tag keeps the last good symbols
    diags = await changed(client, uri, 8, text.replace('<state name="Night" final="true"/>',
                                                       '<state name="Night" final="true"'))
    assert any(d.code == "E002" for d in diags)
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(doc))
    assert syms is not None and [s.name for s in syms if isinstance(s, types.DocumentSymbol)][-1] == "Night"
    closed(client, uri)


async def test_a_library_state_renamed_through_the_server_renames_its_users(
        client: LanguageClient, tmp_path: Path) -> None:
    """The models that use the library are searched in the workspace folder that holds it."""
    lib, user, xml = library_and_users(tmp_path)
    xml.chmod(0o444)
    client.workspace_did_change_workspace_folders(types.DidChangeWorkspaceFoldersParams(
        types.WorkspaceFoldersChangeEvent(added=[types.WorkspaceFolder(tmp_path.as_uri(), "t")],
                                          removed=[])))
    text = lib.read_text()
    uri = await opened(client, lib)
    client.messages.clear()
    edit = await client.text_document_rename_async(types.RenameParams(
        types.TextDocumentIdentifier(uri), position(text, "  Airborne:", delta=3), "InAir"))
    assert edit is not None and edit.changes is not None
    assert set(edit.changes) == {uri, user.resolve().as_uri()}
    utext = user.read_text()
    ulines = Lines(utext)
    new = apply_edits(utext, [TextEdit(ulines.offset(e.range.start), ulines.offset(e.range.end), e.new_text)
                              for e in edit.changes[user.resolve().as_uri()]])
    assert 'active("TakeOff/InAir")' in new and new.replace("InAir", "Airborne") == utext
    for _ in range(100):
        if client.messages:
            break
        await asyncio.sleep(0.05)
    assert any("read-only" in m.message and f"{xml}:" in m.message for m in client.messages)
    closed(client, uri)
    client.workspace_did_change_workspace_folders(types.DidChangeWorkspaceFoldersParams(
        types.WorkspaceFoldersChangeEvent(added=[], removed=[types.WorkspaceFolder(tmp_path.as_uri(), "t")])))


async def test_a_request_right_after_opening_waits_for_the_first_check(client: LanguageClient
                                                                      ) -> None:
    """An editor asks for hover or symbols as soon as it opens a file: the answer waits for the
    document's first analysis instead of being empty."""
    text = MODEL.read_text()
    uri = MODEL.resolve().as_uri()
    client.text_document_did_open(types.DidOpenTextDocumentParams(types.TextDocumentItem(
        uri, "yaml", 1, text)))
    doc = types.TextDocumentIdentifier(uri)
    h = await client.text_document_hover_async(types.HoverParams(doc, position(text, "period: 50ms", delta=2)))
    assert h is not None and "period" in str(h.contents)
    syms = await client.text_document_document_symbol_async(types.DocumentSymbolParams(doc))
    assert syms and {"TakeOff", "Mission"} <= {s.name for s in syms}
    await published(client, uri)
    closed(client, uri)
