"""What the campaign side and the server side of the console share: the beat, the pointer file,
the token's hand-over, the addresses, whether a process lives (no import between the two)."""

from __future__ import annotations

import os

TICK_S = 0.04  # status 25 times a second
LIVE_FILE = "live.json"  # in the campaign folder while a live campaign runs
TOKEN_ENV = "CUTLAB_CONSOLE_TOKEN"  # how a live campaign hands its server the token (not argv)
WILDCARD_BINDS = frozenset({"", "0.0.0.0", "::"})
#: s a live campaign's server stays after the campaign process died (the page says so)
LINGER_S = float(os.environ.get("CUTLAB_CONSOLE_LINGER_S", "600"))


def url_of(bind: str, port: int, token: str) -> str:
    """The address to open, token included (as notebook servers print theirs)."""
    b = bind.strip().strip("[]")
    host = "127.0.0.1" if b in WILDCARD_BINDS else f"[{b}]" if ":" in b else b
    return f"http://{host}:{port}/?token={token}"


def pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
