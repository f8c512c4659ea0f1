"""Who may use the console (issue 31): the Host allowlist, the websocket's Origin, the session's
token (:class:`Guard`, the ASGI middleware in front of the app; rules in
:mod:`rig.console.server`'s docstring), and the page's websocket messages checked
(:func:`parse_message`); refusals and bad messages are one logged line each, within a budget."""

from __future__ import annotations

import contextlib
import ipaddress
import json
import math
import secrets
import socket
import sys
from collections.abc import Awaitable, Callable, Mapping
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qs, urlsplit

from rig.console.common import WILDCARD_BINDS

if TYPE_CHECKING:
    from starlette.datastructures import State

LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
COMMANDS = ("hold", "resume", "abort")
LOG_BUDGET = 20  # logged lines of refusals / bad messages per connection (then one more saying so)


def say(message: str) -> None:
    """One line on stderr (the console's log: refusals, dropped messages, errors)."""
    line = " ".join(str(message).split())[:400]
    with contextlib.suppress(OSError, ValueError):
        print(f"cutlab: console: {line}", file=sys.stderr, flush=True)


def host_allowlist(bind: str) -> frozenset[str]:
    """The host names (lower case, IPv6 without brackets) a request's Host may name: this
    computer's loopback names and the bound address; bound to all addresses, also the computer's
    own names and addresses (:func:`host_allowed` then takes any IP address too)."""
    names = set(LOOPBACK_NAMES)
    b = bind.strip().strip("[]").lower()
    if b in WILDCARD_BINDS:
        with contextlib.suppress(OSError):
            me = socket.gethostname()
            names |= {me.lower(), socket.getfqdn().lower()}
            names |= {str(i[4][0]).lower() for i in socket.getaddrinfo(me, None)}
    else:
        names.add(b)
    return frozenset(names)


def _hostname(netloc: str) -> str | None:
    """The host of ``host[:port]`` (lower case, IPv6 without brackets); None if malformed."""
    if not netloc or "@" in netloc or any(c.isspace() or c in "/?#\\" for c in netloc):
        return None
    try:
        parts = urlsplit("//" + netloc)
        _ = parts.port  # a non-numeric port raises
    except ValueError:
        return None
    return parts.hostname or None


def host_allowed(host: str | None, allow: frozenset[str], any_ip: bool) -> bool:
    if host is None:
        return False
    if host in allow:
        return True
    if any_ip:  # bound to all addresses: an IP address is no DNS name, so cannot be rebound
        with contextlib.suppress(ValueError):
            ipaddress.ip_address(host.split("%")[0])
            return True
    return False


def _peer(scope: Mapping[str, Any]) -> str:
    c = scope.get("client")
    if not c:
        return "an unknown client"
    host, port = c[0], c[1]
    return f"[{host}]:{port}" if ":" in str(host) else f"{host}:{port}"


def cookie_name(port: int) -> str:
    """Cookies are shared by every port of a host: one name per console port."""
    return f"cutlab_console_token_{port}"


Send = Callable[[dict[str, Any]], Awaitable[None]]


class Guard:
    """ASGI middleware in front of the console app: the Host allowlist, the websocket's Origin,
    the token (see the module docstring); and a last net under the app: an exception is one
    logged line and a 500 (or a closed websocket), never an ASGI traceback."""

    #: the inner app's state (rig.console.server.make_app sets it: the hub, the token)
    state: State

    def __init__(self, app: Any, token: str, bind: str = "127.0.0.1") -> None:
        if not token:
            raise ValueError("the console needs a token")
        self.app, self.token = app, token.encode()
        self.allow = host_allowlist(bind)
        self.any_ip = bind.strip().strip("[]") in WILDCARD_BINDS
        self._logged = 0

    def _say(self, message: str) -> None:
        # A page or script knocking in a loop must not fill the campaign's terminal.
        self._logged += 1
        if self._logged <= 10 * LOG_BUDGET:
            say(message)
        elif self._logged == 10 * LOG_BUDGET + 1:
            say("more refusals: not logged")

    def _token_ok(self, given: str | None) -> bool:
        return bool(given) and secrets.compare_digest(str(given).encode(), self.token)

    def check(self, scope: dict[str, Any]) -> tuple[int, str, bool]:
        """(0 or the HTTP status refusing the request, why, the token came in the query)."""
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", [])}  # fmt: skip
        host_header = headers.get("host", "")
        if not host_allowed(_hostname(host_header), self.allow, self.any_ip):
            return 403, f"Host {host_header[:80]!r} is not this computer", False
        if scope["type"] == "websocket":
            origin = headers.get("origin")
            if origin is None:
                return 403, "no Origin (a websocket must come from the console's page)", False
            try:
                o = urlsplit(origin)
                ok = o.scheme in ("http", "https") and o.netloc.lower() == host_header.lower()
            except ValueError:
                ok = False
            if not ok or not host_allowed(_hostname(o.netloc), self.allow, self.any_ip):
                return 403, f"Origin {origin[:80]!r} is not this console's page", False
        if scope["path"].startswith("/static/"):
            return 0, "", False  # the page's scripts and styles: no data
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        in_query = (query.get("token") or [None])[-1]
        if in_query is not None:
            if self._token_ok(in_query):
                return 0, "", True
            return 401, "wrong token", False
        auth = headers.get("authorization", "")
        scheme, _, value = auth.partition(" ")
        if scheme.lower() in ("bearer", "token") and self._token_ok(value.strip()):
            return 0, "", False
        port = (scope.get("server") or ("", 0))[1]
        for part in headers.get("cookie", "").split(";"):
            name, _, value = part.strip().partition("=")
            if name == cookie_name(port) and self._token_ok(value):
                return 0, "", False
        return 401, "no token or a wrong one (open the address printed with its ?token=)", False

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        what = "websocket" if scope["type"] == "websocket" else scope.get("method", "GET")
        where = f"{what} {scope.get('path', '')} from {_peer(scope)}"
        code, why, token_in_query = self.check(scope)
        if code:
            self._say(f"refused {where}: {why}")
            await _refuse(scope, send, code, why)
            return
        started = False

        async def send_on(message: dict[str, Any]) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                if token_in_query:  # later requests of the page carry it by themselves
                    port = (scope.get("server") or ("", 0))[1]
                    cookie = (f"{cookie_name(port)}={self.token.decode()}; Path=/; HttpOnly; "
                              "SameSite=Strict")  # fmt: skip
                    headers = [*message.get("headers", []), (b"set-cookie", cookie.encode())]
                    message = {**message, "headers": headers}
            elif message["type"] in ("websocket.accept", "websocket.close"):
                started = True
            await send(message)

        try:
            await self.app(scope, receive, send_on)
        except Exception as exc:  # noqa: BLE001 - one line, never a traceback in the campaign's log
            self._say(f"error in {where}: {type(exc).__name__}: {exc}")
            if not started:
                with contextlib.suppress(Exception):
                    await _refuse(scope, send, 500, "internal error (logged by the console)")


async def _refuse(scope: dict[str, Any], send: Send, code: int, why: str) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008 if code != 500 else 1011})
        return
    body = json.dumps({"error": why}).encode()
    await send({"type": "http.response.start", "status": code,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode())]})  # fmt: skip
    await send({"type": "http.response.body", "body": body})


def _finite(text: str) -> float:
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"{text[:20]} is out of range")
    return x


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number")


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def parse_message(text: str | None) -> tuple[dict[str, Any] | None, str]:
    """A page's websocket message: (the message, "") or (None, why it is dropped)."""
    if text is None:
        return None, "a binary message (expected JSON text)"
    try:
        msg = json.loads(text, parse_float=_finite, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        return None, f"not JSON ({str(exc)[:80]})"
    if not isinstance(msg, dict):
        return None, f"a JSON {type(msg).__name__} (expected an object with a type)"
    kind = msg.get("type")
    if kind == "hello":
        for key in ("px", "window_s"):
            if key in msg and not _is_number(msg[key]):
                return None, f"hello: {key} = {str(msg[key])[:40]!r}: expected a number"
        return msg, ""
    if kind == "cmd":
        cmd = msg.get("cmd")
        if not isinstance(cmd, str) or cmd not in COMMANDS:
            return None, (f"cmd: {str(cmd)[:40]!r}: unknown command (expected hold, resume or "
                          "abort)")  # fmt: skip
        return msg, ""
    return None, f"type {str(kind)[:40]!r}: unknown (expected hello or cmd)"
