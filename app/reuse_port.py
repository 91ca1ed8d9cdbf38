"""Serve the API from several processes on one port, each accepting on its own socket.

Why not uvicorn's --workers: its processes share one listening socket, and whichever is idle
when a burst of clients connects accepts the burst (its event loop accepts in a loop): under
benchmarks/load.py 31, 32 and 25 of 33 keep-alive connections sat on one of two processes, that
process's GIL held every request on them, and the forecast p99 doubled (benchmarks/RESULTS.md).
Here each process listens on its own socket bound with SO_REUSEPORT, and the kernel spreads
new connections across the sockets by a hash of their addresses (Linux).

    python -m app.reuse_port --fd N    # one process serving on an inherited listening socket
"""

from __future__ import annotations

import argparse
import signal
import socket
import subprocess
import sys
import time
from types import FrameType

from app import logs
from app.config import KEEP_ALIVE_SECONDS, get_settings

BACKLOG = 2048  # uvicorn's default


def listening_socket(host: str, port: int) -> socket.socket:
    """A socket on host:port that other processes' sockets may share (SO_REUSEPORT)."""
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    sock.bind((host, port))
    sock.listen(BACKLOG)
    sock.set_inheritable(True)
    return sock


def serve_processes(host: str, port: int, processes: int) -> int:
    """Run `processes` API processes, each on its own SO_REUSEPORT socket on host:port, until a
    signal (SIGTERM, SIGINT: passed on to them) or until one exits (the others are then stopped,
    so a supervisor restarts the service whole).  Returns the exit status."""
    sockets = [listening_socket(host, port) for _ in range(processes)]
    children = [
        subprocess.Popen(
            [sys.executable, "-m", "app.reuse_port", "--fd", str(sock.fileno())],
            pass_fds=(sock.fileno(),),
        )
        for sock in sockets
    ]
    for sock in sockets:
        sock.close()  # the children hold them now
    signalled = False

    def pass_on(signum: int) -> None:
        for child in children:
            if child.poll() is None:
                child.send_signal(signum)

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        nonlocal signalled
        signalled = True
        pass_on(signum)

    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, on_signal)
    while all(child.poll() is None for child in children):
        time.sleep(0.2)
    if not signalled:
        pass_on(signal.SIGTERM)
    codes = [child.wait() for child in children]
    return 0 if signalled else next((code for code in codes if code), 1)


def main() -> None:
    """One API process on the listening socket inherited as --fd."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fd", type=int, required=True)
    fd = parser.parse_args().fd
    import uvicorn

    settings = get_settings()
    logs.configure(settings.log_format, settings.log_level)
    uvicorn.run(
        "app.main:app",
        fd=fd,
        log_config=None,
        access_log=False,
        timeout_keep_alive=KEEP_ALIVE_SECONDS,
    )


if __name__ == "__main__":
    main()
