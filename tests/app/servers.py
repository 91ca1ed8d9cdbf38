"""Real service processes for end-to-end and crash tests: `python -m uvicorn app.main:app` and
`fleetpinn worker`, each on the database the test names, logging to a file in its folder."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

# Small fleets and a physics model keep jobs short; a test overrides what it needs.
BASE_ENV = {
    "FLEETPINN_KERNEL": "physics",
    "FLEETPINN_WORKER_POLL_SECONDS": "0.05",
    "FLEETPINN_POSTERIOR_RESTARTS": "2",
    "OMP_NUM_THREADS": "1",
}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class Process:
    """A child process of the service with its log; kill() is a real SIGKILL."""

    def __init__(self, command: list[str], env: dict[str, str], log: Path) -> None:
        self.log = log
        self._log = log.open("ab")
        self.process = subprocess.Popen(
            command, env={**os.environ, **env}, stdout=self._log, stderr=subprocess.STDOUT
        )

    def kill(self) -> None:
        """kill -9: no handler runs, no transaction is committed or rolled back by the process."""
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(timeout=30)
        self._log.close()

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.kill()
        self._log.close()

    def text(self) -> str:
        return self.log.read_text(errors="replace")


class Server(Process):
    """`python -m uvicorn app.main:app` on a free loopback port, ready when /health answers."""

    def __init__(self, database_url: str, folder: Path, **env: str) -> None:
        self.port = free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        command = [sys.executable, "-m", "uvicorn", "app.main:app", "--port", str(self.port)]
        environment = {**BASE_ENV, "FLEETPINN_DATABASE_URL": database_url, **env}
        super().__init__(command, environment, folder / f"server-{self.port}.log")
        self._wait_ready()

    def _wait_ready(self, timeout_s: float = 90.0) -> None:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                if httpx.get(f"{self.base}/health", timeout=1).status_code == 200:
                    return
            except httpx.TransportError:
                pass
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"server did not start:\n{self.text()}")
            time.sleep(0.1)

    def client(self, timeout_s: float = 60.0) -> httpx.Client:
        return httpx.Client(base_url=self.base, timeout=timeout_s)


def worker(database_url: str, folder: Path, name: str, **env: str) -> Process:
    """A `fleetpinn worker` process polling the jobs table."""
    fleetpinn = str(Path(sys.executable).parent / "fleetpinn")
    environment = {**BASE_ENV, "FLEETPINN_DATABASE_URL": database_url, **env}
    return Process([fleetpinn, "worker"], environment, folder / f"worker-{name}.log")
