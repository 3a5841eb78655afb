"""Whom the web view answers: the one who has its URL, in a page of its own (docs/web.md, "Trust").

As Jupyter's server does, every run makes a random token and prints it in the
URL; opening that URL trades the token for an HttpOnly, SameSite=Strict cookie
and redirects to the clean URL. Every route (the page, its files, ``/sub``,
``/ws``) then needs the cookie (or the token in the query, for a script), and

- ``Host`` must be a loopback name, the address or name the server was started
  on, or one given with ``--allow-host``: a page from a name that a DNS server
  made point here (DNS rebinding) is refused even before the token is looked at;
- ``Origin``, when the browser sends one (always on a WebSocket), must be the
  page's own: a page of another origin (another port of 127.0.0.1, a ``file://``
  page, whose origin is ``null``) cannot open ``/ws`` even with the cookie, which
  a browser also sends to other ports of the same host;
- a browser's subresource request from another origin (``Sec-Fetch-Site``) is refused;
- every answer forbids framing (``frame-ancestors 'none'``, ``X-Frame-Options``)
  and sniffing, sends no referrer, and keeps the page's window to itself.
"""

from __future__ import annotations

import hmac
import secrets
import socket
import sys
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass
from typing import TextIO

from aiohttp import web
from aiohttp.typedefs import Middleware

from hfsmc.hosts import host_name, is_loopback, is_unspecified, normal_name

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]
# What every answer carries beside its own Content-Security-Policy.
HEADERS = {"X-Frame-Options": "DENY", "X-Content-Type-Options": "nosniff",
           "Referrer-Policy": "no-referrer", "Cross-Origin-Opener-Policy": "same-origin",
           "Cross-Origin-Resource-Policy": "same-origin"}
CSP_OTHER = "default-src 'none'; frame-ancestors 'none'"  # what is not the page itself
REFUSALS_LOGGED = 32  # distinct refusals said on stderr; later ones are not


@dataclass(frozen=True)
class Trust:
    """The run's token, its cookie's name and the names (besides loopback ones) that
    the pages may be served under."""

    token: str
    cookie: str
    names: frozenset[str] = frozenset()

    @classmethod
    def new(cls, sock: socket.socket, named: str | None = None,
            allow: Iterable[str] = ()) -> Trust:
        """A fresh token for the server on ``sock``, started on the host ``named``
        (``--web HOST:PORT``) and allowed the names ``allow`` (``--allow-host``,
        already checked with ``hfsmc.hosts.allowed_name``)."""
        host, port = sock.getsockname()[:2]
        names = {n for n in (normal_name(host), normal_name(named or "")) if n is not None}
        names = {n for n in names if not is_unspecified(n)} | set(allow)
        return cls(secrets.token_urlsafe(32), f"hfsmc-view-{port}", frozenset(names))

    def allows(self, name: str) -> bool:
        return is_loopback(name) or name in self.names

    def token_ok(self, given: str | None) -> bool:
        # Compared as bytes: compare_digest refuses a str that is not ASCII.
        return given is not None and hmac.compare_digest(given.encode("utf-8", "replace"),
                                                         self.token.encode("ascii"))


def loopback_only(sock: socket.socket) -> bool:
    """Whether ``sock`` listens on a loopback address only."""
    return is_loopback(normal_name(sock.getsockname()[0]) or "")


def guard(trust: Trust, log: TextIO | None = None) -> Middleware:
    """The middleware that refuses what is not the user's own page (see the module's doc)."""
    said: set[str] = set()

    def refuse(request: web.Request, why: str, detail: str) -> web.Response:
        line = f"hfsmc view: refused {request.method} {request.path}: {why}"
        if line not in said and len(said) < REFUSALS_LOGGED:
            said.add(line)
            print(line, file=log if log is not None else sys.stderr, flush=True)
        return web.Response(status=403, text=f"hfsmc view: {why}. {detail}\n",
                            headers={"Cache-Control": "no-store"})

    @web.middleware
    async def check(request: web.Request, handler: Handler) -> web.StreamResponse:
        header = request.headers.get("Host", "")
        name = host_name(header)
        if name is None or not trust.allows(name):
            shown = (name or header)[:80]
            return refuse(request, f"the Host {shown!r} is not a name this web view answers to",
                          f"Start hfsmc view with --allow-host {shown} to view it under that "
                          "name (docs/web.md, Trust).")
        origin = request.headers.get("Origin")
        if origin is not None and origin.lower() not in (f"http://{header.lower()}",
                                                         f"https://{header.lower()}"):
            return refuse(request, f"a page of another origin ({origin[:80]}) may not use "
                          "this web view", "Open the web view's own page.")
        navigating = request.path == "/" and request.headers.get("Sec-Fetch-Mode",
                                                                 "navigate") == "navigate"
        site = request.headers.get("Sec-Fetch-Site", "same-origin")
        if not navigating and site not in ("same-origin", "none"):
            return refuse(request, f"a {site} request may not use this web view",
                          "Open the web view's own page.")
        given = request.query.get("token")
        if request.path == "/" and given is not None:
            if not trust.token_ok(given):
                return refuse(request, "wrong token", "Open the URL this run of hfsmc view "
                              "printed: each run has a token of its own.")
            return _enter(trust, cross_site=site not in ("same-origin", "none", "same-site"))
        if not (trust.token_ok(request.cookies.get(trust.cookie)) or trust.token_ok(given)):
            return refuse(request, "no token", "Open the URL hfsmc view printed, with its "
                          "?token=...: each run has a token of its own.")
        return await handler(request)

    return check


def _enter(trust: Trust, cross_site: bool) -> web.Response:
    """The token's URL: the cookie, and the clean URL. After a link from another site a
    redirect would not carry a SameSite=Strict cookie, so the page itself goes on."""
    if cross_site:
        response = web.Response(text='<!doctype html><meta http-equiv="refresh" content="0; url=/">'
                                '<title>hfsmc view</title><a href="/">hfsmc view</a>\n',
                                content_type="text/html")
    else:
        response = web.Response(status=303, headers={"Location": "/"})
    response.headers["Cache-Control"] = "no-store"
    response.set_cookie(trust.cookie, trust.token, httponly=True, samesite="Strict", path="/")
    return response


async def headers(request: web.Request, response: web.StreamResponse) -> None:
    """``on_response_prepare``: what every answer carries (framing, sniffing, referrer)."""
    for key, value in HEADERS.items():
        response.headers.setdefault(key, value)
    response.headers.setdefault("Content-Security-Policy", CSP_OTHER)
