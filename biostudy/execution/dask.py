"""Cases on a Dask cluster (docs/clusters.md), and the choice between it and local workers.

A cluster is named by its scheduler's address or by the scheduler file it
wrote (``dask scheduler --scheduler-file FILE``, how a batch job started
inside an allocation is found: docs/clusters.md).

The cluster's workers do all of a case's work (`worker.perform`): each receives
a `worker.Task` (the compiled problem, plain arrays) and hands back its
`worker.Outcome` with the case file's bytes, which this process puts in place
without reading them (`jobs`), so the workers need no shared filesystem.  Dask's nanny
starts its workers with one thread per library, and a case runs on one thread
unless its scene names more (``[numerics] threads``): the processors of a node
are shared by worker processes that no one of them sees.  A `tls://` scheduler needs
Dask's TLS configuration (certificates), checked before anything runs.

What a user is told, in one line each, instead of Dask's tracebacks: an
address where nothing listens (at once, not after Dask's retries); one where
nothing answers as a Dask scheduler (even one that accepts the connection and
then says nothing) within `CONNECT_TIMEOUT`; a scheduler with
no workers ("waiting for workers on ADDR", again every `NOTICE_EVERY`
seconds while there are none); a scheduler lost while the sweep runs
(`SchedulerLost`: the caller says what was kept and how to resume).
Distributed's own log lines are held back in this process while a sweep
uses the cluster.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import socket
import uuid
from pathlib import Path
from typing import Callable

from ..errors import BadInput, Failed, first_line
from ..inputs.files import read_text
from . import interrupts
from .worker import Outcome, Task, perform

CONNECT_TIMEOUT = 10.0  # seconds to reach a Dask scheduler and hear it answer
NOTICE_EVERY = 30.0  # seconds between two "waiting for workers" notices
SCHEDULER_FILE_BYTES = 16 << 20  # 16 MiB: Dask's identity of its scheduler, with every worker's


class SchedulerLost(Failed):
    """The connection to the Dask scheduler broke while cases ran on it."""


def scheduler_address(scheduler_file: str | Path) -> str:
    """The address a Dask scheduler wrote into its scheduler file (`dask scheduler --scheduler-file FILE`, a JSON
    object with "address"); `BadInput` if the file is missing, no regular file of at most `SCHEDULER_FILE_BYTES`
    (`files.read_text`: a FIFO would block, /dev/zero fill the memory) or holds none.  Dask is handed the
    address, never the file."""
    path = Path(scheduler_file)
    try:
        text = read_text(path, SCHEDULER_FILE_BYTES, "a Dask scheduler file")
    except BadInput as error:
        hint = (" (has the Dask scheduler started? `dask scheduler --scheduler-file FILE` writes it)"
                if error.problem == "no such file" else "")
        raise BadInput(error.problem + hint, path, "--scheduler-file") from None
    try:
        address = json.loads(text).get("address")
    except (ValueError, AttributeError) as error:
        raise BadInput(f"not a Dask scheduler file ({first_line(error)})", path, "--scheduler-file") from None
    except RecursionError:  # '[[[[...': json's decoder recurses once per level
        raise BadInput("not a Dask scheduler file (nested too deeply)", path, "--scheduler-file") from None
    if not isinstance(address, str) or "://" not in address:
        raise BadInput("not a Dask scheduler file (no \"address\" in it)", path, "--scheduler-file")
    return address


def runs_here(scheduler: str | None, scheduler_file: str | Path | None = None) -> bool:
    """True when the jobs run on this machine (serially or on local processes), not on a Dask cluster: then a
    case too big for this machine's memory is refused by the command's pre-flight (`inputs.resources.Preflight`)."""
    return not (scheduler or scheduler_file)


def check_choice(workers: int | None, scheduler: str | None, scheduler_file: str | Path | None = None) -> None:
    """Jobs run on local processes or on a Dask cluster (its address or its scheduler file), not both; a
    tls:// scheduler needs Dask's TLS configuration (certificates), which a plain Dask client would only miss
    with a traceback."""
    given = [name for name, value in (("--workers", workers), ("--scheduler", scheduler),
                                      ("--scheduler-file", scheduler_file)) if value]
    if len(given) > 1:
        raise BadInput(f"give {given[0]} or {given[1]}, not both" if len(given) == 2 else
                       "give one of --workers, --scheduler and --scheduler-file", given[0])
    if scheduler_file:
        scheduler = scheduler_address(scheduler_file)
    if scheduler and scheduler.startswith("tls://"):
        from distributed.security import Security  # Dask only when a cluster is asked for

        try:
            context = Security().get_connection_args("client").get("ssl_context")
        except (OSError, ValueError) as error:  # a configured certificate that cannot be read
            raise BadInput(f"Dask's TLS configuration cannot be used: {error}", "--scheduler") from None
        if context is None:
            raise BadInput(f"{scheduler} needs a TLS configuration: Dask's distributed.comm.tls.ca-file, "
                           ".client.cert and .client.key (a YAML file in DASK_CONFIG; docs/clusters.md, 'Local "
                           "workers and a Dask cluster')", "--scheduler")


def _refused(address: str, timeout: float) -> bool:
    """Whether a TCP address (tcp://, tls://) refuses connections: nothing listens there.  Dask's connect
    retries a refused connection until its deadline and then says it timed out, as for a silent peer."""
    from urllib.parse import urlsplit

    parts = urlsplit(address)
    try:
        host, port = parts.hostname, parts.port
    except ValueError:  # a port that is no number: Dask says so
        return False
    if parts.scheme not in ("tcp", "tls") or not host or port is None:
        return False
    try:
        socket.create_connection((host, port), timeout).close()
    except ConnectionRefusedError:
        return True
    except OSError:  # unreachable, unknown host, silent: Dask's connect tells
        return False
    return False


def _identity(address: str, timeout: float) -> dict:
    """What the scheduler at `address` says it is, asked directly with a deadline over connecting, the
    handshake and the answer (Dask's own connect waits forever for a peer that accepts and then says nothing)."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed.comm import connect
    from distributed.security import Security

    async def ask() -> dict:
        comm = await connect(address, timeout=timeout, **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            await comm.close()

    with ThreadPoolExecutor(1) as thread:  # a loop of its own, also where one runs already (a notebook)
        return thread.submit(asyncio.run, asyncio.wait_for(ask(), timeout)).result()


class _Quiet:
    """distributed's loggers in this process held to CRITICAL until `restore`."""

    def __init__(self):
        names = ["distributed", *(n for n in logging.root.manager.loggerDict if n.startswith("distributed."))]
        self.levels = {name: logging.getLogger(name).level for name in names}
        for name in names:
            logging.getLogger(name).setLevel(logging.CRITICAL)

    def restore(self) -> None:
        for name, level in self.levels.items():
            logging.getLogger(name).setLevel(level)


class DaskCluster:
    """A `backends.Backend` on a running Dask scheduler: twice as many cases in flight as the cluster has
    threads (at least 4); closing cancels the cases still submitted.  note(message) hears what a user should
    know while waiting (no workers)."""

    sees_files = False  # its workers may be on machines that do not see the sweep's directory

    def __init__(self, address: str | None, note: Callable[[str], None] = lambda message: None,
                 scheduler_file: str | Path | None = None):
        from distributed import Client

        option = "--scheduler"
        if address is None:
            address, option = scheduler_address(scheduler_file), "--scheduler-file"
        self.address, self.note = address, note
        if _refused(address, CONNECT_TIMEOUT):
            raise BadInput(f"nothing listens at {address} (connection refused): is a Dask scheduler running there?",
                           option)
        try:
            found = _identity(address, CONNECT_TIMEOUT)
        except TimeoutError:
            raise BadInput(f"cannot connect to a Dask scheduler at {address}: nothing answered within "
                           f"{CONNECT_TIMEOUT:g} s (a program that accepts the connection but is no Dask scheduler, "
                           "or one that is stuck)", option) from None
        except (OSError, ValueError, TypeError) as error:
            raise BadInput(f"cannot connect to a Dask scheduler at {address} ({error})", option) from None
        if not isinstance(found, dict) or found.get("type") != "Scheduler":
            kind = found.get("type", "something else") if isinstance(found, dict) else "something else"
            raise BadInput(f"{address} is not a Dask scheduler (it answers as {kind})", option)
        self.quiet = _Quiet()
        try:
            self.client = Client(address, timeout=f"{CONNECT_TIMEOUT}s")
        except (OSError, TimeoutError, ValueError) as error:
            self.quiet.restore()
            raise BadInput(f"cannot connect to a Dask scheduler at {address} ({error})", option) from None
        threads = sum(self.client.nthreads().values())
        self.capacity = max(4, 2 * threads)
        self.running: dict = {}  # future -> case id
        self.tag = uuid.uuid4().hex[:8]  # keys of this sweep's tasks, apart from any other client's
        if not threads:
            self._waiting()

    @property
    def busy(self) -> int:
        return len(self.running)

    def submit(self, case_id: str, task: Task) -> None:
        problem = task.problem
        if problem.numerics.threads is None:  # a node's processors are shared by worker processes no one of them sees
            problem = dataclasses.replace(problem, numerics=dataclasses.replace(problem.numerics, threads=1))
        future = self.client.submit(perform, dataclasses.replace(task, problem=problem),
                                    key=f"biostudy-{case_id}-{self.tag}", pure=False)
        self.running[future] = case_id

    def _lost(self, error: BaseException) -> SchedulerLost:
        from concurrent.futures import CancelledError

        reason = ("the connection to it broke" if isinstance(error, CancelledError) or not str(error)
                  else str(error).splitlines()[0][:200])
        return SchedulerLost(f"lost the Dask scheduler at {self.address} ({reason})")

    def _waiting(self) -> None:
        """Say so if the scheduler has no workers (then the cases wait)."""
        try:
            workers = self.client.nthreads()
        except Exception as error:  # the scheduler is gone too
            raise self._lost(error) from None
        if not workers:
            waiting = f" ({len(self.running)} cases submitted wait for them)" if self.running else ""
            self.note(f"waiting for workers on {self.address}: none is connected{waiting}")

    def finished(self) -> list[tuple[str, Outcome]]:
        from distributed import wait

        while True:
            try:
                with interrupts.allowed():  # waiting: an interruption ends it (`backends.windowed`)
                    done = wait(list(self.running), timeout=NOTICE_EVERY, return_when="FIRST_COMPLETED").done
            except TimeoutError:
                self._waiting()
                continue
            except Exception as error:  # cancelled by a lost connection, or the connection's own error
                raise self._lost(error) from None
            if done:
                return [(self.running.pop(future), self._outcome(future)) for future in done]

    def _outcome(self, future) -> Outcome:
        from concurrent.futures import CancelledError  # what distributed raises for a cancelled future

        try:
            return future.result()
        except CancelledError as error:  # this sweep cancels nothing while it runs: the scheduler went away
            raise self._lost(error) from None
        except Exception as error:  # e.g. KilledWorker: the case took its worker down
            return Outcome("failed", f"{type(error).__name__}: {error}", float("nan"), type(error).__name__)

    def close(self, completed: bool) -> None:
        try:
            if self.running:
                self.client.cancel(list(self.running))
            self.client.close(timeout=CONNECT_TIMEOUT)
        except Exception:
            pass  # a scheduler already gone: nothing left to cancel
        finally:
            self.quiet.restore()
