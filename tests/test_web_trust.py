"""The web view answers only its user (docs/web.md, "Trust"): the token of the URL it prints,
traded for a cookie; Host and Origin; the headers; a bind that other machines reach.

Each test runs `hfsmc view --web` on a free port (a replay of the blinker's trace: no
component needed), asks it in plain HTTP with the headers a browser or an attacker would
send, and, where a browser is the attacker, drives Debian's chromium: a page of another
local origin, a `file://` page and a name that a DNS server pointed at 127.0.0.1."""

from __future__ import annotations

import contextlib
import http.client
import http.server
import json
import re
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from hfsmc.commands.view import view
from hfsmc.web.server import SCRIPTS
from tests.support import (
    BLINKER,
    RECORDS,
    ROOT,
    WEB_URL,
    Process,
    needs_browser,
    screenshot,
    wait_until,
)

HANDSHAKE = {"Upgrade": "websocket", "Connection": "Upgrade", "Sec-WebSocket-Version": "13",
             "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="}


class Web:
    """`hfsmc view --web` replaying the blinker's trace; its URL, port and token."""

    def __init__(self, logged: Callable[..., Process], tmp: Path, *args: str) -> None:
        trace = tmp / "blinker.trace"
        if not trace.exists():
            trace.write_text("".join(json.dumps(r) + "\n" for r in RECORDS))
        self.p = logged([sys.executable, "-m", "hfsmc", "view", "--web", *args, "--replay",
                         str(trace), "--model", str(ROOT / BLINKER)], "web")
        self.url = self.p.wait_for(WEB_URL, where="out").group(1)
        m = re.fullmatch(r"http://127\.0\.0\.1:(\d+)/\?token=([\w-]+)", self.url)
        assert m, self.url
        self.port, self.token = int(m[1]), m[2]
        self.cookie = f"hfsmc-view-{self.port}={self.token}"

    def ask(self, path: str, headers: dict[str, str] | None = None,
            host: str | None = None) -> tuple[int, http.client.HTTPMessage, str]:
        """GET ``path`` with ``headers`` (Host: 127.0.0.1:PORT unless ``host`` is given)."""
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=10)
        try:
            given = {"Host": host if host is not None else f"127.0.0.1:{self.port}",
                     **(headers or {})}
            conn.request("GET", path, headers=given)
            r = conn.getresponse()
            body = b"" if r.status == 101 else r.read()
            return r.status, r.headers, body.decode("utf-8", "replace")
        finally:
            conn.close()

    def err(self) -> str:
        return self.p.err_path.read_text()

    def says(self, text: str, timeout: float = 5) -> bool:
        """Whether ``text`` appears on the web view's stderr within ``timeout`` seconds."""
        return wait_until(lambda: text in self.err(), timeout)


@pytest.fixture
def web(logged: Callable[..., Process], tmp_path: Path) -> Web:
    return Web(logged, tmp_path, "0")


def test_every_route_needs_the_token_of_the_run(web: Web) -> None:
    scripts = [f"/{name}" for name in SCRIPTS]
    routes = ["/", *scripts, "/app.css", "/sub?state=Blinking", "/favicon.ico", "/ws"]
    for path in routes:
        extra = HANDSHAKE if path == "/ws" else {}
        for cookie in ({}, {"Cookie": f"hfsmc-view-{web.port}=nope"},
                       {"Cookie": f"hfsmc-view-{web.port + 1}={web.token}"}):
            status, _, text = web.ask(path, {**extra, **cookie})
            assert (status, text) == (403, "hfsmc view: no token. Open the URL hfsmc view "
                                      "printed, with its ?token=...: each run has a token of "
                                      "its own.\n"), (path, cookie)
    for wrong in ("nope", "%C3%A9t%C3%A9", web.token[:-1], web.token + "x", ""):
        status, _, text = web.ask(f"/?token={wrong}")
        assert status == 403 and text.startswith("hfsmc view: wrong token."), wrong
    # The token's URL: a cookie for this port's web view alone, and the clean URL.
    status, headers, _ = web.ask(f"/?token={web.token}")
    assert status == 303 and headers["Location"] == "/"
    assert headers["Set-Cookie"] == (f"hfsmc-view-{web.port}={web.token}; HttpOnly; Path=/; "
                                     "SameSite=Strict")
    for path, want in (("/", 200), *((script, 200) for script in scripts), ("/app.css", 200),
                       ("/sub?state=Blinking", 200), ("/sub?state=Nope", 404),
                       ("/favicon.ico", 204), ("/ws", 101)):
        extra = HANDSHAKE if path == "/ws" else {}
        status, headers, text = web.ask(path, {"Cookie": web.cookie, **extra})
        assert status == want, (path, status, text)
        if status != 101:
            assert "frame-ancestors 'none'" in headers["Content-Security-Policy"], path
            assert headers["X-Frame-Options"] == "DENY", path
            assert headers["X-Content-Type-Options"] == "nosniff", path
            assert headers["Referrer-Policy"] == "no-referrer", path
    # A script gives the token in the query instead of the cookie.
    assert web.ask(f"/ws?token={web.token}", HANDSHAKE)[0] == 101
    assert web.ask(f"/app.js?token={web.token}")[0] == 200
    err = web.err()
    assert "hfsmc view: refused GET /app.js: no token\n" in err
    assert err.count("refused GET /app.js: no token") == 1, err  # said once
    assert "warning" not in err  # on loopback: nothing to warn about


def test_the_page_loads_the_scripts_served_and_nothing_else_is_served(web: Web) -> None:
    html = (ROOT / "hfsmc/web/static/index.html").read_text()
    loaded = re.findall(r"<script\b[^>]*>", html)
    # Each script a file of its own (no inline code: the CSP allows none), in the server's order.
    assert loaded == [f'<script src="{name}">' for name in SCRIPTS], loaded
    assert loaded[-1] == '<script src="app.js">'  # the start, once the parts are defined
    for name in SCRIPTS:
        status, headers, text = web.ask(f"/{name}", {"Cookie": web.cookie})
        assert status == 200 and headers["Content-Type"] == "text/javascript; charset=utf-8", name
        assert "script-src 'self';" in headers["Content-Security-Policy"], name
        assert text == (ROOT / "hfsmc/web/static" / name).read_text(), name
        assert "eval(" not in text and "new Function" not in text, name
    # The package's other files (the editor's page, its bundle, the Python) are not the
    # view's: not served, even with the cookie.
    for path in ("/editor.js", "/editor.html", "/index.html", "/server.py", "/static/app.js",
                 "/vendor/codemirror.js", "/app.js/", "/APP.JS", "/page.js.map"):
        assert web.ask(path, {"Cookie": web.cookie})[0] == 404, path


def test_the_websocket_opens_only_for_the_page_s_own_origin(web: Web) -> None:
    own = f"http://127.0.0.1:{web.port}"
    ws = {"Cookie": web.cookie, **HANDSHAKE}
    assert web.ask("/ws", {**ws, "Origin": own})[0] == 101
    assert web.ask("/ws", {**ws, "Origin": f"http://localhost:{web.port}"},
                   host=f"localhost:{web.port}")[0] == 101
    assert web.ask("/ws", ws)[0] == 101  # no Origin: not a browser, and it has the token
    for origin in (f"http://127.0.0.1:{web.port + 1}", "null", "http://evil.test",
                   f"http://localhost:{web.port}", f"{own}.evil.test", f"{own}/x"):
        status, _, text = web.ask("/ws", {**ws, "Origin": origin})
        assert status == 403 and "may not use this web view" in text, origin
        assert web.ask(f"/ws?token={web.token}", {**HANDSHAKE, "Origin": origin})[0] == 403
    assert f"refused GET /ws: a page of another origin (http://127.0.0.1:{web.port + 1})" \
        in web.err()
    # A browser's request for a file or a drawing from another site, even with the cookie.
    for site in ("cross-site", "same-site"):
        for path in ("/app.js", "/sub?state=Blinking", "/ws"):
            asked = {"Cookie": web.cookie, "Sec-Fetch-Site": site, "Sec-Fetch-Mode": "no-cors",
                     **(HANDSHAKE if path == "/ws" else {})}
            assert web.ask(path, asked)[0] == 403, (site, path)
    # A link from another site to the token's URL: a redirect would lose a SameSite=Strict
    # cookie, so the page sets it and goes on to the clean URL itself.
    status, headers, text = web.ask(f"/?token={web.token}", {"Sec-Fetch-Site": "cross-site",
                                                             "Sec-Fetch-Mode": "navigate"})
    assert status == 200 and 'http-equiv="refresh" content="0; url=/"' in text
    assert headers["Set-Cookie"].startswith(f"hfsmc-view-{web.port}={web.token}; HttpOnly")


def test_only_loopback_names_and_the_allowed_ones_are_answered(web: Web) -> None:
    cookie = {"Cookie": web.cookie}
    for host in (f"localhost:{web.port}", f"[::1]:{web.port}", "127.0.0.1", "LOCALHOST",
                 f"127.1.2.3:{web.port}", f"view.localhost:{web.port}"):
        assert web.ask("/", cookie, host=host)[0] == 200, host
    for host in (f"evil.test:{web.port}", "127.0.0.1.nip.io", "evil.test", "a b", "",
                 f"127.0.0.1:{web.port}:1", "[::1", "0.0.0.0", "x" * 400):
        status, _, text = web.ask("/", cookie, host=host)
        assert status == 403 and "is not a name this web view answers to" in text, host
        assert web.ask(f"/?token={web.token}", host=host)[0] == 403  # the token does not help
    _, _, text = web.ask("/", cookie, host=f"evil.test:{web.port}")
    assert "Start hfsmc view with --allow-host evil.test" in text
    assert "refused GET /: the Host 'evil.test' is not a name this web view answers to" \
        in web.err()


def test_a_network_bind_warns_and_answers_the_allowed_names_with_the_token(
        logged: Callable[..., Process], tmp_path: Path) -> None:
    web = Web(logged, tmp_path, "0.0.0.0:0", "--allow-host", "Robot.Test.",
              "--allow-host", "192.0.2.7")
    warning = web.p.wait_for(r"hfsmc view: warning: .*\n").group(0)
    assert warning == (f"hfsmc view: warning: the web view on 0.0.0.0:{web.port} can be reached "
                       "from other machines: whoever has its URL with the token sees the "
                       "component's states, variables, log and camera, unencrypted; it answers "
                       "to loopback names and to these others (--allow-host): 192.0.2.7, "
                       "robot.test\n")
    for host in (f"robot.test:{web.port}", "192.0.2.7", f"localhost:{web.port}"):
        assert web.ask("/", {"Cookie": web.cookie}, host=host)[0] == 200, host
        assert web.ask("/", host=host)[0] == 403, host  # the token all the same
        assert web.ask("/ws", {"Cookie": web.cookie, **HANDSHAKE,
                               "Origin": f"http://{host}"}, host=host)[0] == 101
    for host in ("other.test", "192.0.2.8", f"0.0.0.0:{web.port}"):
        assert web.ask("/", {"Cookie": web.cookie}, host=host)[0] == 403, host


def test_allow_host_usage_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    trace = tmp_path / "t.trace"
    trace.write_text(json.dumps(RECORDS[0]) + "\n")
    for bad in ("a b", "robot:8080", "0.0.0.0", "::", "", "-x"):
        assert view(None, str(trace), web="0", allow_hosts=(bad,)) == 2, bad
        assert capsys.readouterr().err == (f"hfsmc: error: bad --allow-host {bad!r}: expected a "
                                           "host name or an IP address, without a port\n")
    assert view(None, str(trace), allow_hosts=("robot.test",)) == 2
    assert capsys.readouterr().err == ("hfsmc: error: --allow-host is for the web view "
                                       "(--web [HOST:]PORT)\n")


# -- a browser as the attacker ---------------------------------------------------------------------
# A page that tries to read the web view at PORT: its WebSocket, a drawing, and the page in a frame.
ATTACK = """<!doctype html><title>attack</title>
<iframe id="frame" src="http://127.0.0.1:PORT/"></iframe>
<script>
window.seen = {ws: [], fetch: null};
const ws = new WebSocket("ws://127.0.0.1:PORT/ws");
ws.onopen = () => seen.ws.push("open");
ws.onmessage = (e) => seen.ws.push("message " + String(e.data).slice(0, 40));
ws.onclose = (e) => seen.ws.push("close");
fetch("http://127.0.0.1:PORT/sub?state=Blinking", {credentials: "include"})
  .then((r) => r.text()).then((t) => { seen.fetch = "read " + t.length; },
                              () => { seen.fetch = "refused"; });
</script>
"""


@contextlib.contextmanager
def pages(files: dict[str, str]) -> Iterator[int]:
    """Another local web server (127.0.0.1, a free port) serving ``files``; its port."""
    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = files.get(self.path.split("?")[0], "").encode()
            self.send_response(200 if body else 404)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    try:
        yield int(server.server_address[1])
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


def attacked(driver: Any) -> dict[str, Any]:
    """What the attack page got once its WebSocket and its fetch have ended."""
    deadline = time.monotonic() + 10
    while True:
        seen: dict[str, Any] = driver.execute_script("return window.seen || null;") or {}
        if "close" in seen.get("ws", []) and seen.get("fetch") is not None:
            return seen
        assert time.monotonic() < deadline, seen
        time.sleep(0.05)


def the_view_is_shown(driver: Any) -> bool:
    """Whether the page drew the replay's diagram (its model's states)."""
    return bool(driver.execute_script(
        "return document.body.dataset.status === 'replay' && "
        "document.querySelectorAll('#hv-diagram g.node').length >= 4;"))


@needs_browser
def test_a_page_of_another_origin_cannot_use_the_web_view(
        web: Web, browsers: Callable[..., Any], tmp_path: Path) -> None:
    driver = browsers()
    driver.get(web.url)  # the user's own page: the cookie is set, the view drawn
    assert wait_until(lambda: the_view_is_shown(driver), 15), driver.page_source[:500]
    assert driver.current_url == f"http://127.0.0.1:{web.port}/"  # the token is gone from it
    screenshot(driver, "web-trust-own-page", tmp_path)
    attack = ATTACK.replace("PORT", str(web.port))
    with pages({"/attack.html": attack}) as other:
        # Another port of 127.0.0.1 (same site: the browser sends the cookie), then localhost.
        for origin in (f"http://127.0.0.1:{other}", f"http://localhost:{other}"):
            driver.get(f"{origin}/attack.html")
            seen = attacked(driver)
            assert seen == {"ws": ["close"], "fetch": "refused"}, (origin, seen)
            assert web.says(f"refused GET /ws: a page of another origin ({origin})"), web.err()
            driver.switch_to.frame(driver.find_element("id", "frame"))
            assert driver.find_elements("id", "hv-diagram") == []  # not drawn in a frame
            driver.switch_to.default_content()
    # A page saved on disk: its origin is null.
    saved = tmp_path / "attack.html"
    saved.write_text(attack)
    driver.get(saved.as_uri())
    assert attacked(driver) == {"ws": ["close"], "fetch": "refused"}
    assert web.says("refused GET /ws: a page of another origin (null)"), web.err()
    # The user's page still works.
    driver.get(f"http://127.0.0.1:{web.port}/")
    assert wait_until(lambda: the_view_is_shown(driver), 15)


@needs_browser
def test_a_name_pointed_at_loopback_is_refused_unless_allowed(
        logged: Callable[..., Process], browsers: Callable[..., Any], tmp_path: Path) -> None:
    """DNS rebinding: the browser resolves rebind.test to 127.0.0.1 (as a DNS server of the
    attacker's would); the page under that name is refused, even with the token."""
    web = Web(logged, tmp_path, "0")
    driver = browsers("--host-resolver-rules=MAP rebind.test 127.0.0.1",
                      "--disable-features=HttpsUpgrades")
    driver.get(f"http://rebind.test:{web.port}/?token={web.token}")
    text = driver.find_element("tag name", "body").text
    assert "the Host 'rebind.test' is not a name this web view answers to" in text, text
    assert driver.get_cookies() == []
    # Named with --allow-host, the same name is served (the name does reach the web view).
    allowed = Web(logged, tmp_path, "0", "--allow-host", "rebind.test")
    driver.get(f"http://rebind.test:{allowed.port}/?token={allowed.token}")
    assert wait_until(lambda: the_view_is_shown(driver), 15), driver.page_source[:500]
    assert driver.current_url == f"http://rebind.test:{allowed.port}/"


@needs_browser
def test_a_link_from_another_site_opens_the_page(web: Web, browsers: Callable[..., Any]) -> None:
    """The token's URL followed from a page of another site (a SameSite=Strict cookie is not
    sent after a cross-site redirect): the user's page opens all the same."""
    driver = browsers()
    link = f'<!doctype html><a id="go" href="{web.url}">the view</a>'
    with pages({"/links.html": link}) as other:
        driver.get(f"http://localhost:{other}/links.html")
        driver.find_element("id", "go").click()
        assert wait_until(lambda: the_view_is_shown(driver), 15), driver.page_source[:500]
    assert driver.current_url == f"http://127.0.0.1:{web.port}/"



@needs_browser
def test_a_page_left_open_across_a_restart_says_its_token_is_not_accepted(
        logged: Callable[..., Process], browsers: Callable[..., Any], tmp_path: Path) -> None:
    web = Web(logged, tmp_path, "0")
    driver = browsers()
    driver.get(web.url)
    assert wait_until(lambda: the_view_is_shown(driver), 15)
    assert web.p.kill(signal.SIGTERM) == 0
    again = Web(logged, tmp_path, str(web.port))  # the same port, a new token
    banner = ("this page's token is not accepted (the web view was started again?): open the "
              "URL hfsmc view printed")
    assert wait_until(lambda: driver.find_element("id", "hv-banner").text == banner, 15)
    assert again.says("refused GET /ws: no token")
    driver.get(again.url)
    assert wait_until(lambda: the_view_is_shown(driver), 15)
