"""The protocol side of ``hfsmc lsp``: pygls on stdio, incremental sync, diagnostics
debounced as the text changes (C++ snippets through g++ on save), and a file changed on
disk under unsaved edits reported as a conflict (SPEC 8.1)."""

from __future__ import annotations

import asyncio
import os
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse

from lsprotocol import types
from pygls.exceptions import JsonRpcInvalidParams
from pygls.lsp.server import LanguageServer

from hfsmc.edit.text import EditError
from hfsmc.lsp import features
from hfsmc.lsp.analysis import Analysis, analyse, is_model, lsp_diagnostics

DEBOUNCE_S = float(os.environ.get("HFSMC_LSP_DEBOUNCE_MS", "150")) / 1000


@dataclass
class Doc:
    """An open document: its latest analysis and what the disk held when it was read."""

    uri: str
    path: str
    analysis: Analysis | None = None
    disk: str | None = None
    task: asyncio.Task[None] | None = None
    published: frozenset[str] = frozenset()
    conflict: bool = False


def path_of(uri: str) -> str:
    p = urlparse(uri)
    return unquote(p.path) if p.scheme == "file" else uri


def _read(path: str) -> str | None:
    try:
        return Path(path).read_text("utf-8")
    except (OSError, UnicodeDecodeError):
        return None


class HfsmcServer(LanguageServer):
    def __init__(self) -> None:
        super().__init__("hfsmc", "0.1.0")
        self.docs: dict[str, Doc] = {}

    def text(self, uri: str) -> str:
        return self.workspace.get_text_document(uri).source

    def model_doc(self, uri: str) -> Doc | None:
        doc = self.docs.get(uri)
        return doc if doc is not None and doc.analysis is not None else None

    async def ready(self, uri: str) -> Doc | None:
        """The open model once it has an analysis: a request that comes right after
        didOpen waits for the first check instead of answering nothing."""
        doc = self.docs.get(uri)
        while doc is not None and doc.analysis is None and doc.task is not None \
                and not doc.task.done():
            await asyncio.wait({doc.task})  # a newer change may cancel it: then its successor
            doc = self.docs.get(uri)
        return self.model_doc(uri)

    async def refresh(self, uri: str, delay: float, cxx: bool = False) -> None:
        """Check the document after ``delay`` (a newer change cancels this one)."""
        if delay:
            await asyncio.sleep(delay)
        doc = self.docs.get(uri)
        if doc is None:
            return
        text = self.text(uri)
        if not is_model(text):
            doc.analysis = None
            self._publish(doc, {})
            return
        last = doc.analysis
        loop = asyncio.get_running_loop()
        a = await loop.run_in_executor(None, analyse, doc.path, text, last, cxx)
        if self.text(uri) != text:
            return  # changed meanwhile: the next check publishes
        doc.analysis = a
        self._publish(doc, lsp_diagnostics(a))
        self._watch_disk(doc, text)

    def _publish(self, doc: Doc, by_file: dict[str, list[types.Diagnostic]]) -> None:
        uris = {features.uri_of(f) if f != doc.path else doc.uri: d for f, d in by_file.items()}
        uris.setdefault(doc.uri, [])
        for uri in doc.published - set(uris):
            self.text_document_publish_diagnostics(types.PublishDiagnosticsParams(uri, []))
        for uri, diags in uris.items():
            self.text_document_publish_diagnostics(types.PublishDiagnosticsParams(uri, diags))
        doc.published = frozenset(uris)

    def _watch_disk(self, doc: Doc, text: str) -> None:
        """A file changed on disk since it was read, while the editor holds other text."""
        now = _read(doc.path)
        if now is None or doc.disk is None or now == doc.disk or now == text:
            doc.conflict = False
            return
        if not doc.conflict:
            doc.conflict = True
            self.window_show_message(types.ShowMessageParams(
                types.MessageType.Warning,
                f"hfsmc: {doc.path} changed on disk under unsaved edits: a conflict to resolve "
                "(reload it, or save over it on purpose)"))

    def schedule(self, uri: str, delay: float, cxx: bool = False) -> None:
        doc = self.docs[uri]
        if doc.task is not None and not doc.task.done():
            doc.task.cancel()
        doc.task = asyncio.ensure_future(self.refresh(uri, delay, cxx))


server = HfsmcServer()


@server.feature(types.TEXT_DOCUMENT_DID_OPEN)
async def did_open(ls: HfsmcServer, params: types.DidOpenTextDocumentParams) -> None:
    uri = params.text_document.uri
    path = path_of(uri)
    ls.docs[uri] = Doc(uri, path, disk=_read(path))
    ls.schedule(uri, 0, cxx=True)


@server.feature(types.TEXT_DOCUMENT_DID_CHANGE)
async def did_change(ls: HfsmcServer, params: types.DidChangeTextDocumentParams) -> None:
    if params.text_document.uri in ls.docs:
        ls.schedule(params.text_document.uri, DEBOUNCE_S)


@server.feature(types.TEXT_DOCUMENT_DID_SAVE)
async def did_save(ls: HfsmcServer, params: types.DidSaveTextDocumentParams) -> None:
    doc = ls.docs.get(params.text_document.uri)
    if doc is not None:
        doc.disk = _read(doc.path)
        doc.conflict = False
        ls.schedule(doc.uri, 0, cxx=True)


@server.feature(types.TEXT_DOCUMENT_DID_CLOSE)
async def did_close(ls: HfsmcServer, params: types.DidCloseTextDocumentParams) -> None:
    doc = ls.docs.pop(params.text_document.uri, None)
    if doc is not None:
        for uri in doc.published:
            ls.text_document_publish_diagnostics(types.PublishDiagnosticsParams(uri, []))


@server.feature(types.WORKSPACE_DID_CHANGE_WATCHED_FILES)
async def watched(ls: HfsmcServer, params: types.DidChangeWatchedFilesParams) -> None:
    for change in params.changes:
        doc = ls.docs.get(change.uri)
        if doc is not None:
            ls._watch_disk(doc, ls.text(doc.uri))


async def _at(ls: HfsmcServer, uri: str, pos: types.Position) -> tuple[Analysis, int] | None:
    doc = await ls.ready(uri)
    if doc is None or doc.analysis is None:
        return None
    a = doc.analysis
    return a, a.lines.offset(pos)


@server.feature(types.TEXT_DOCUMENT_DEFINITION)
async def definition(ls: HfsmcServer, params: types.DefinitionParams) -> types.Location | None:
    at = await _at(ls, params.text_document.uri, params.position)
    return features.definition(*at) if at else None


@server.feature(types.TEXT_DOCUMENT_REFERENCES)
async def references(ls: HfsmcServer, params: types.ReferenceParams) -> list[types.Location]:
    at = await _at(ls, params.text_document.uri, params.position)
    return features.references(*at, params.context.include_declaration) if at else []


@server.feature(types.TEXT_DOCUMENT_RENAME)
async def rename(ls: HfsmcServer, params: types.RenameParams) -> types.WorkspaceEdit | None:
    at = await _at(ls, params.text_document.uri, params.position)
    if at is None:
        return None
    a, off = at
    if a.text != ls.text(params.text_document.uri):  # the analysis is behind the text
        a = analyse(a.path, ls.text(params.text_document.uri), a)
        off = a.lines.offset(params.position)
    try:
        roots = [path_of(f.uri) for f in ls.workspace.folders.values()]
        if ls.workspace.root_path and ls.workspace.root_path not in roots:
            roots.append(ls.workspace.root_path)
        edit, left = features.rename(a, off, params.new_name, roots)
    except EditError as e:
        raise JsonRpcInvalidParams(str(e)) from None
    if left is not None:
        ls.window_show_message(types.ShowMessageParams(types.MessageType.Warning, f"hfsmc: {left}"))
    return edit


@server.feature(types.TEXT_DOCUMENT_COMPLETION,
                types.CompletionOptions(trigger_characters=[".", "$", '"', "/", ":", " "]))
async def completion(ls: HfsmcServer, params: types.CompletionParams) -> types.CompletionList:
    doc = await ls.ready(params.text_document.uri)
    if doc is None or doc.analysis is None:
        return types.CompletionList(False, [])
    text = ls.text(params.text_document.uri)
    a = doc.analysis
    if a.text != text:
        a = a.for_text(text)
    return types.CompletionList(False, features.completion(a, a.lines.offset(params.position)))


@server.feature(types.TEXT_DOCUMENT_HOVER)
async def hover(ls: HfsmcServer, params: types.HoverParams) -> types.Hover | None:
    at = await _at(ls, params.text_document.uri, params.position)
    if at is None:
        return None
    a, off = at
    diags = lsp_diagnostics(a).get(a.path, [])
    return features.hover(a, off, diags)


@server.feature(types.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
async def symbols(ls: HfsmcServer, params: types.DocumentSymbolParams) -> list[types.DocumentSymbol]:
    doc = await ls.ready(params.text_document.uri)
    return features.symbols(doc.analysis) if doc is not None and doc.analysis is not None else []


@server.feature(types.TEXT_DOCUMENT_CODE_ACTION,
                types.CodeActionOptions(code_action_kinds=[types.CodeActionKind.QuickFix]))
async def code_action(ls: HfsmcServer, params: types.CodeActionParams) -> list[types.CodeAction]:
    doc = await ls.ready(params.text_document.uri)
    if doc is None or doc.analysis is None:
        return []
    return features.code_actions(doc.analysis, params.text_document.uri, params.context.diagnostics)


def main() -> None:
    """Serve on stdin/stdout until the client says exit."""
    server.start_io()
