"""The service as a real uvicorn process on a loopback port, for end-to-end tests and benchmarks.

They drive fleetpinn over HTTP the way a client does.  This module is their one way to start it
(or a `fleetpinn worker` process), to know it is up (GET /health answers 200), to wait for a
job and to stop it (or kill it: crash tests), so a change to how the service starts or reports a
finished job is made here once.
"""

from __future__ import annotations

import os
import resource
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import httpx

from app.config import KEEP_ALIVE_SECONDS
from app.services.jobs.queue import FINISHED

_POLL_S = 0.1


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class ServiceProcess:
    """A started service process whose output goes to `log`; stop() ends it politely, kill()
    with SIGKILL (no handler runs, no transaction is committed or rolled back by it).
    address_space_bytes: a limit of its virtual memory (RLIMIT_AS): an allocation past it fails
    in the process (a MemoryError), as a container's memory limit would stop it."""

    def __init__(
        self,
        command: Sequence[str],
        env: Mapping[str, str],
        log: Path,
        address_space_bytes: int | None = None,
    ) -> None:
        self.log = log
        self._output = log.open("ab")

        def limited() -> None:
            if address_space_bytes is not None:
                limit = (address_space_bytes, address_space_bytes)
                resource.setrlimit(resource.RLIMIT_AS, limit)

        self.process = subprocess.Popen(
            list(command),
            env={**os.environ, **env},
            stdout=self._output,
            stderr=subprocess.STDOUT,
            preexec_fn=limited if address_space_bytes is not None else None,
        )
        self.base = ""

    def peak_rss_bytes(self) -> int:
        """The most resident memory the (running) process has held: VmHWM (Linux)."""
        status = Path(f"/proc/{self.process.pid}/status").read_text()
        kib = next(line.split()[1] for line in status.splitlines() if line.startswith("VmHWM:"))
        return int(kib) * 1024

    def kill(self) -> None:
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(timeout=60)
        self._output.close()

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.kill()
        self._output.close()

    def text(self) -> str:
        return self.log.read_text(errors="replace")


def start_uvicorn(
    app: str,
    env: Mapping[str, str],
    log: Path,
    *,
    uvicorn_args: Sequence[str] = (),
    startup_s: float = 120.0,
    address_space_bytes: int | None = None,
) -> ServiceProcess:
    """`python -m uvicorn app` on a free 127.0.0.1 port, returned (its URL in .base) once GET
    /health answers 200; uvicorn_args: further options, e.g. ("--workers", "2");
    address_space_bytes: its memory limit (ServiceProcess).  Raises RuntimeError with the log's
    text when it does not."""
    port = _free_port()
    keep_alive = ("--timeout-keep-alive", str(KEEP_ALIVE_SECONDS))  # as `fleetpinn serve`
    command = [
        sys.executable,
        "-m",
        "uvicorn",
        app,
        "--port",
        str(port),
        *keep_alive,
        *uvicorn_args,
    ]
    return _healthy(command, env, log, port, startup_s, address_space_bytes)


def start_service(
    env: Mapping[str, str], log: Path, *, processes: int = 1, startup_s: float = 120.0
) -> ServiceProcess:
    """`fleetpinn serve --processes N` on a free 127.0.0.1 port, as a deployment runs it
    (migrations first; more than one process: app.reuse_port), returned (its URL in .base)
    once GET /health answers 200.  Raises RuntimeError with the log's text when it does not."""
    port = _free_port()
    fleetpinn = str(Path(sys.executable).parent / "fleetpinn")
    command = [fleetpinn, "serve", "--port", str(port), "--processes", str(processes)]
    return _healthy(command, env, log, port, startup_s)


def _healthy(
    command: Sequence[str],
    env: Mapping[str, str],
    log: Path,
    port: int,
    startup_s: float,
    address_space_bytes: int | None = None,
) -> ServiceProcess:
    """The server `command` started, serving on 127.0.0.1:port once /health answers; stopped
    and RuntimeError raised when it does not."""
    server = ServiceProcess(command, env, log, address_space_bytes)
    server.base = f"http://127.0.0.1:{port}"
    try:
        _wait_until_healthy(server.base, server.process, startup_s, log)
    except RuntimeError:
        server.stop()
        raise
    return server


def start_worker(env: Mapping[str, str], log: Path) -> ServiceProcess:
    """A `fleetpinn worker` process polling the jobs table of FLEETPINN_DATABASE_URL."""
    fleetpinn = str(Path(sys.executable).parent / "fleetpinn")
    return ServiceProcess([fleetpinn, "worker"], env, log)


@contextmanager
def uvicorn_server(
    app: str,
    env: Mapping[str, str],
    *,
    factory: bool = False,
    log: Path | None = None,
    uvicorn_args: Sequence[str] = (),
    startup_s: float = 120.0,
) -> Iterator[str]:
    """Run `python -m uvicorn app` on a free 127.0.0.1 port; yield its base URL
    ("http://127.0.0.1:port") once GET /health answers 200; terminate it on exit.

    app: "module:attribute" (with factory, a function that returns the app); env: variables set
    over this process's environment (FLEETPINN_* settings); log: file that receives the
    server's stdout and stderr (None: this process's); uvicorn_args: further options, e.g.
    ("--log-level", "warning").  Raises RuntimeError, with the log's text where there is one,
    when the server exits or does not answer within startup_s seconds.
    """
    port = _free_port()
    command = [sys.executable, "-m", "uvicorn", *(["--factory"] if factory else [])]
    command += [app, "--port", str(port), "--timeout-keep-alive", str(KEEP_ALIVE_SECONDS)]
    command += uvicorn_args
    base = f"http://127.0.0.1:{port}"
    with ExitStack() as stack:
        output = stack.enter_context(log.open("wb")) if log is not None else None
        process = subprocess.Popen(
            command,
            env={**os.environ, **env},
            stdout=output,
            stderr=subprocess.STDOUT if output is not None else None,
        )
        try:
            _wait_until_healthy(base, process, startup_s, log)
            yield base
        finally:
            process.terminate()
            process.wait(timeout=60)


def _wait_until_healthy(
    base: str, process: subprocess.Popen[bytes], startup_s: float, log: Path | None
) -> None:
    deadline = time.monotonic() + startup_s
    while True:
        try:
            if httpx.get(f"{base}/health", timeout=1).status_code == 200:
                return
        except httpx.TransportError:
            pass
        if process.poll() is not None or time.monotonic() > deadline:
            output = log.read_text() if log is not None else "(output not captured)"
            raise RuntimeError(f"the server at {base} did not start:\n{output}")
        time.sleep(_POLL_S)


def wait_for_job(client: httpx.Client, job_id: str, timeout_s: float = 300.0) -> dict[str, Any]:
    """GET /jobs/{job_id} until the job has finished (succeeded, failed or cancelled); its JSON.

    client: any httpx client of the service, FastAPI's TestClient included.  Raises TimeoutError
    when the job has not finished after timeout_s seconds: a bound on a job that hangs, not a
    timing (a retrain of a small fleet took 65 s on a 2-core machine running the suite beside
    it, and a 60 s bound failed it).
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job: dict[str, Any] = client.get(f"/jobs/{job_id}").json()
        if job["status"] in FINISHED:
            return job
        time.sleep(0.05)
    raise TimeoutError(f"job {job_id} did not finish in {timeout_s} s")
