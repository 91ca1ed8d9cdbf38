"""`fleetpinn serve --processes 2` (app.reuse_port): each process accepts on its own socket of
one port, so new connections reach both; the processes stop together."""

from __future__ import annotations

import os
import signal
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.local_server import ServiceProcess, start_service
from tests.app.servers import BASE_ENV


def _children(pid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.fixture
def service(tmp_path: Path) -> Iterator[ServiceProcess]:
    env = {**BASE_ENV, "FLEETPINN_DATABASE_URL": f"sqlite:///{tmp_path / 'fleet.db'}"}
    server = start_service(env, tmp_path / "serve.log", processes=2)
    yield server
    server.stop()


def _wait_exit(server: ServiceProcess, seconds: float = 30.0) -> int:
    return server.process.wait(timeout=seconds)


def _established(pid: int, port: int, peers: set[int]) -> int:
    """Established TCP connections on local `port` from one of the local ports `peers` (this
    test's clients: a client of another test, whose server's port this one reused, may connect
    too) among the sockets process `pid` holds."""
    held = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        target = os.readlink(fd)
        if target.startswith("socket:["):
            held.add(target[8:-1])
    count = 0
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            local_port = int(fields[1].rsplit(":", 1)[1], 16)
            peer = int(fields[2].rsplit(":", 1)[1], 16)
            if local_port == port and peer in peers and fields[3] == "01" and fields[9] in held:
                count += 1
    return count


def test_new_connections_reach_both_processes_and_a_signal_stops_them(
    service: ServiceProcess,
) -> None:
    """Sixteen connections held open: both processes hold some (all on one by chance:
    2**-15); with uvicorn's --workers a burst of them landed on one (31 of 33 measured).  Then
    SIGTERM stops the service and every process of it (one service for both: each start takes
    ~10 s of CPU)."""
    port = int(service.base.rsplit(":", 1)[1])
    children = _children(service.process.pid)
    clients = [socket.create_connection(("127.0.0.1", port), timeout=30) for _ in range(16)]
    try:
        for client in clients:  # answered: a process accepted it, and keeps it alive
            client.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            assert client.recv(4096).startswith(b"HTTP/1.1 200")
        peers = {client.getsockname()[1] for client in clients}
        held = [_established(pid, port, peers) for pid in children]
    finally:
        for client in clients:
            client.close()
    assert len(held) == 2
    assert sum(held) == 16
    assert min(held) >= 1

    service.process.send_signal(signal.SIGTERM)
    assert _wait_exit(service) == 0
    deadline = time.monotonic() + 30
    while any(_alive(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in children)


def test_a_process_that_dies_stops_the_service(service: ServiceProcess) -> None:
    """So a supervisor (systemd, Docker) restarts it whole rather than serving on half."""
    first, second = _children(service.process.pid)
    os.kill(first, signal.SIGKILL)
    assert _wait_exit(service) != 0
    deadline = time.monotonic() + 30
    while _alive(second) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(second)
