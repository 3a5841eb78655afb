"""Action and service servers scripted by an ``hfsmc test`` scenario (docs/testing.md,
"Action servers and service responses"), answered by the ``ros2`` playback fake.

Copied beside a component with a ``ros2`` interface. A scenario's script gives, per action
or service, the server that holds from an entry's time on (``servers`` in a snapshot
entry; ``null``: none from then on). A goal or a call is answered by the server that held
when it was sent, from the instant after, at the times the server says (relative to the
goal or the call), never within the instant it was sent (``pending`` then), as a real
server's answers come between instants:

- an action: ``{"accept": bool, "feedback": [[after_us, CDR], ...], "after_us": int|null,
  "end": "succeeded"|"aborted", "result": CDR|null}``: rejected, or executing with the
  latest feedback due, then the end with its result (the default ``Result`` when none);
  a cancel from the model makes it ``canceled`` at the next instant;
- a service: ``{"response": CDR|null, "after_us": int}``: ``done`` with the response;
- no server: ``no_server`` until the model's time limit (``timeout``).
"""

from __future__ import annotations

import base64
import binascii
from typing import Any

if __package__:
    from . import hfsmc_ros2_cdr as cdr
else:  # beside the generated component
    import hfsmc_ros2_cdr as cdr  # type: ignore[import-not-found, no-redef]

ENDS = ("succeeded", "aborted")


def convert(values: Any, acts: dict[str, Any], srvs: dict[str, Any]) -> dict[str, Any]:
    """A script's ``servers`` checked and decoded (ValueError says what is wrong)."""
    if not isinstance(values, dict):
        raise ValueError("`servers` must be a mapping")
    out: dict[str, Any] = {}
    for n, p in values.items():
        if n not in acts and n not in srvs:
            raise ValueError(f"no action or service `{n}` "
                             f"({', '.join([*acts, *srvs]) or 'none'})")
        if p is None:
            out[n] = None
            continue
        if not isinstance(p, dict):
            raise ValueError(f"`servers.{n}` must be a mapping or null")
        after = p.get("after_us")
        if after is not None and (isinstance(after, bool) or not isinstance(after, int)
                                  or after < 0):
            raise ValueError(f"`servers.{n}.after_us` must be a whole number >= 0 or null")
        cls = acts[n]["class"] if n in acts else srvs[n]["class"]
        if n in srvs:
            out[n] = {"response": _message(cls.Response, p.get("response"), n),
                      "after_us": after or 0}
            continue
        if p.get("end", "succeeded") not in ENDS or not isinstance(p.get("accept", True), bool):
            raise ValueError(f"`servers.{n}`: `accept` true or false, `end` one of "
                             f"{', '.join(ENDS)}")
        feedback = []
        for item in p.get("feedback") or ():
            if not (isinstance(item, list) and len(item) == 2 and isinstance(item[0], int)):
                raise ValueError(f"`servers.{n}.feedback`: a list of [after_us, CDR]")
            feedback.append((item[0], _message(cls.Feedback, item[1], n)))
        out[n] = {"accept": p.get("accept", True), "feedback": sorted(feedback,
                                                                      key=lambda f: f[0]),
                  "after_us": after, "end": p.get("end", "succeeded"),
                  "result": _message(cls.Result, p.get("result"), n)}
    return out


def _message(cls: Any, text: Any, n: str) -> Any:
    if text is None:
        return None
    try:
        return cdr.deserialize(cls, base64.b64decode(str(text), validate=True))
    except (binascii.Error, ValueError) as e:
        raise ValueError(f"`servers.{n}`: no {cls._TYPE}: {e}") from None


class Scripted:
    """The goals and calls a scripted server answers (one per action and service)."""

    def __init__(self, acts: dict[str, Any], srvs: dict[str, Any]) -> None:
        self.acts, self.srvs = acts, srvs
        self.holding: dict[str, Any] = {}  # name -> the server that holds now (None: none)
        self.every = False  # a scenario's script: an action or a service without a server
        # name -> [sent at, delivered at (None: no server yet), its server, cancelled at]
        self.sent: dict[str, list[Any]] = {}

    def scripted(self, name: str) -> bool:
        return self.every or name in self.holding

    def send(self, name: str, t_us: int) -> None:
        server = self.holding.get(name)
        self.sent[name] = [t_us, t_us if server is not None else None, server, None]

    def cancel(self, name: str, t_us: int) -> None:
        if name in self.sent:
            self.sent[name][3] = t_us

    def _delivered(self, name: str, now: int) -> list[Any] | None:
        """The goal's or call's record; one held for want of a server is delivered to the
        server that holds now, as a live client sends it once the server is matched."""
        sent = self.sent.get(name)
        if sent is not None and sent[1] is None and self.holding.get(name) is not None:
            sent[1], sent[2] = now, self.holding[name]
        return sent

    def goal(self, name: str, now: int) -> tuple[str, Any, Any] | None:
        """(status, feedback, result) of the goal of ``name`` at ``now``; None before any."""
        sent = self._delivered(name, now)
        if sent is None:
            return None
        t0, t, s, cancelled = sent
        if now <= t0:
            return ("pending", None, None)
        limit = self.acts[name]["timeout"]
        late = limit is not None and now - t0 >= limit * 1e6
        if t is None or now <= t:
            return ("timeout" if late else "no_server" if t is None else "pending", None, None)
        if not s["accept"]:
            return ("rejected", None, None)
        cls = self.acts[name]["class"]
        if cancelled is not None and now > cancelled:
            return ("canceled", None, cls.Result())
        due = [m for at, m in s["feedback"] if at <= now - t]
        feedback = due[-1] if due else None
        if s["after_us"] is not None and now - t >= s["after_us"]:
            return (s["end"], feedback, s["result"] if s["result"] is not None else cls.Result())
        return ("timeout" if late else "executing", feedback, None)

    def call(self, name: str, now: int) -> tuple[str, Any] | None:
        """(status, response) of the call of ``name`` at ``now``; None before any."""
        sent = self._delivered(name, now)
        if sent is None:
            return None
        t0, t, s, _ = sent
        if now <= t0:
            return ("pending", None)
        if t is not None and now > t and now - t >= s["after_us"]:
            cls = self.srvs[name]["class"]
            return ("done", s["response"] if s["response"] is not None else cls.Response())
        limit = self.srvs[name]["timeout"]
        if limit is not None and now - t0 >= limit * 1e6:
            return ("timeout", None)
        return ("pending" if t is not None else "no_server", None)
