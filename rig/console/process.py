"""The console server's process beside a live campaign: the console extra and the port checked,
the server started with the session's token, stopped or left to linger, and what a killed
campaign left behind removed."""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from analysis.errors import ConfigError
from rig.console.common import LINGER_S, LIVE_FILE, TOKEN_ENV, pid_alive, url_of
from rig.console.ring import RingError


def check_console_extra() -> None:
    """ConfigError naming the install line when the console's packages are missing."""
    import importlib.util

    missing = [m for m in ("starlette", "uvicorn", "websockets") if not importlib.util.find_spec(m)]
    if missing:
        raise ConfigError(
            f"the live console needs {', '.join(missing)}: pip install -e '.[console]'"
        )


def check_port(bind: str, port: int) -> None:
    """ConfigError when ``bind:port`` cannot be listened on (in use, no such address)."""
    if not 0 < port < 65536:
        raise ConfigError(f"--port = {port}: expected a TCP port 1..65535")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((bind, port))
        except OSError as exc:
            raise ConfigError(
                f"console: cannot listen on {bind}:{port}: {exc.strerror or exc} (another "
                "console or program uses it? choose another --port)"
            ) from None


def start_server(
    target: Path, port: int, bind: str, token: str, timeout_s: float = 20.0
) -> subprocess.Popen:
    """The console server for ``target`` in its own process (its own session: Ctrl-C at the
    campaign's terminal is the campaign's), with the session's ``token`` (in its environment,
    not its command line); returns once it answers."""
    cmd = [sys.executable, "-m", "rig.console.server", str(target), "--port", str(port),
           "--bind", bind, "--linger-s", str(LINGER_S)]  # fmt: skip
    env = {**os.environ, TOKEN_ENV: token}
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, start_new_session=True, env=env)
    url = url_of(bind, port, token).split("?")[0] + "api/health"
    ask = urllib.request.Request(url, headers={"Authorization": f"Bearer {token}"})
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if proc.poll() is not None:
            raise ConfigError(f"console: the server exited at start (status {proc.returncode})")
        with contextlib.suppress(OSError):
            with urllib.request.urlopen(ask, timeout=1.0) as r:
                if r.status == 200:
                    return proc
        time.sleep(0.1)
    proc.terminate()
    raise ConfigError(f"console: the server did not answer on {url} within {timeout_s:.0f} s")


def stop_server(proc: subprocess.Popen, grace_s: float = 1.0) -> None:
    """Let the page see the final state for ``grace_s``, then end the server."""
    if proc.poll() is None:
        time.sleep(grace_s)
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def leave_server(proc: subprocess.Popen, url: str) -> None:
    """The campaign has ended: its server stays (the page switches to browsing the runs) for
    ``LINGER_S`` (``CUTLAB_CONSOLE_LINGER_S``), then exits by itself; said on stderr with its
    process id. Without a linger it is stopped now."""
    if proc.poll() is not None:
        return
    if LINGER_S <= 0:
        stop_server(proc)
        return
    proc.returncode = 0  # not waited for: it outlives this process (no ResourceWarning)
    with contextlib.suppress(OSError):  # the next live campaign on this port ends it
        _linger_file(url).write_text(str(proc.pid))
    print(f"cutlab: the console stays at {url} for {LINGER_S:.0f} s to browse the runs "
          f"(server process {proc.pid})", file=sys.stderr, flush=True)  # fmt: skip


def _linger_file(url: str) -> Path:
    from rig.console.ring import default_ring_path

    port = url.split("/")[2].rsplit(":", 1)[-1]
    return default_ring_path().parent / f"cutlab-console-{os.getuid()}-{port}.linger"


def end_lingering(bind: str, port: int) -> None:
    """A console this user left on ``port`` to browse a finished campaign is ended, so a new
    live campaign can take the port (only a process that is still that server)."""
    f = _linger_file(url_of(bind, port, ""))
    try:
        pid = int(f.read_text().strip() or 0)
    except (OSError, ValueError):
        return
    f.unlink(missing_ok=True)
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return
    if b"rig.console.server" not in cmdline:
        return  # the PID is another process's now
    with contextlib.suppress(OSError):
        os.kill(pid, 15)
        t_end = time.monotonic() + 5.0
        while pid_alive(pid) and time.monotonic() < t_end:
            with contextlib.suppress(ChildProcessError):  # our own child: reaped here
                os.waitpid(pid, os.WNOHANG)
            time.sleep(0.05)


def _beating(ring: Path) -> bool:
    """The ring's writer beat within the last 10 s and has not closed it (a PID alone may have
    been reused by another process)."""
    from rig.console.ring import RingReader

    try:
        r = RingReader(ring)
    except RingError:
        return False
    try:
        return not r.closed and r.heartbeat_age_s() < 10.0
    finally:
        r.close()


def _ring_pid(path: Path) -> int:
    """The writer's PID from a ring file's name (``cutlab-live-PID-N.ring``), else 0."""
    parts = path.name.split("-")
    return int(parts[2]) if len(parts) == 4 and parts[2].isdigit() else 0


def remove_stale(folder: Path) -> list[Path]:
    """Remove what a killed live campaign left (issue 31): ``folder/live.json`` and the ring it
    names when their process is dead, and this user's other rings in the ring folder whose
    process is dead. A live campaign's are kept; ``live.json`` of another live process in this
    folder is an error (its campaign runs). Returns what was removed."""
    from rig.console.ring import default_ring_path

    removed: list[Path] = []
    pointer = folder / LIVE_FILE
    try:
        ptr = json.loads(pointer.read_text())
    except (OSError, ValueError):
        ptr = None if not pointer.exists() else {}
    if ptr is not None:
        pid = int(ptr.get("pid", 0) or 0) if isinstance(ptr, dict) else 0
        ring = Path(str(ptr.get("ring", ""))) if isinstance(ptr, dict) else None
        if pid != os.getpid() and pid_alive(pid) and ring is not None and _beating(ring):
            raise ConfigError(
                f"{pointer}: the live campaign of process {pid} is running in this folder"
            )
        if ring is not None and ring.name.startswith("cutlab-live-") and ring.suffix == ".ring":
            with contextlib.suppress(OSError):
                ring.unlink()
                removed.append(ring)
        with contextlib.suppress(OSError):
            pointer.unlink()
            removed.append(pointer)
    # Rings whose live.json was never written or was removed: those of dead processes of ours;
    # the notes of lingering consoles that have gone.
    uid = os.getuid()
    for note in default_ring_path().parent.glob(f"cutlab-console-{uid}-*.linger"):
        with contextlib.suppress(OSError, ValueError):
            if not pid_alive(int(note.read_text().strip() or 0)):
                note.unlink()
    for ring in default_ring_path().parent.glob("cutlab-live-*.ring"):
        pid = _ring_pid(ring)
        with contextlib.suppress(OSError):
            if pid and pid != os.getpid() and ring.stat().st_uid == uid and not pid_alive(pid):
                ring.unlink()
                removed.append(ring)
    return removed
