"""Cases on a Dask cluster (README, "Sweeps on a Dask cluster"), and the choice between it and local workers.

A cluster is named by its scheduler's address or by the scheduler file it
wrote (``dask scheduler --scheduler-file FILE``, how a batch job started
inside an allocation is found: README, "Batch clusters").

The cluster's workers only simulate: each receives a compiled `solver.Problem`
(plain arrays) and returns the dataset or the reason it failed; this process
writes every file, so the workers need no shared filesystem.  Dask's nanny
starts its workers with one thread per library.  A `tls://` scheduler needs
Dask's TLS configuration (certificates), checked before anything runs.
"""
from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import BadInput, first_line
from .worker import Outcome, solve

if TYPE_CHECKING:
    import solver

CONNECT_TIMEOUT = "10s"  # to reach a Dask scheduler


def scheduler_address(scheduler_file: str | Path) -> str:
    """The address a Dask scheduler wrote into its scheduler file (`dask scheduler --scheduler-file FILE`, a JSON
    object with "address"); `BadInput` if the file is missing or holds none."""
    path = Path(scheduler_file)
    try:
        address = json.loads(path.read_text(encoding="utf-8")).get("address")
    except FileNotFoundError:
        raise BadInput("no such file (has the Dask scheduler started? `dask scheduler --scheduler-file FILE` "
                       "writes it)", path, "--scheduler-file") from None
    except (OSError, UnicodeDecodeError, ValueError, AttributeError) as error:
        raise BadInput(f"not a Dask scheduler file ({first_line(error)})", path, "--scheduler-file") from None
    if not isinstance(address, str) or "://" not in address:
        raise BadInput("not a Dask scheduler file (no \"address\" in it)", path, "--scheduler-file")
    return address


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
                           ".client.cert and .client.key (a YAML file in DASK_CONFIG; README, 'Sweeps on a "
                           "Dask cluster')", "--scheduler")


class DaskCluster:
    """A `backends.Backend` on a running Dask scheduler: twice as many cases in flight as the cluster has
    threads (at least 4); closing cancels the cases still submitted."""

    def __init__(self, address: str | None, scheduler_file: str | Path | None = None):
        from distributed import Client

        option = "--scheduler"
        if address is None:
            address, option = scheduler_address(scheduler_file), "--scheduler-file"
        try:
            self.client = Client(address, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as error:
            raise BadInput(f"cannot connect to a Dask scheduler at {address} ({error})", option) from None
        self.capacity = max(4, 2 * sum(self.client.nthreads().values()))
        self.running: dict = {}  # future -> case id
        self.tag = uuid.uuid4().hex[:8]  # keys of this sweep's tasks, apart from any other client's

    @property
    def busy(self) -> int:
        return len(self.running)

    def submit(self, case_id: str, problem: "solver.Problem") -> None:
        future = self.client.submit(solve, problem, key=f"biostudy-{case_id}-{self.tag}", pure=False)
        self.running[future] = case_id

    def finished(self) -> list[tuple[str, Outcome]]:
        from distributed import wait

        done = wait(list(self.running), return_when="FIRST_COMPLETED").done
        return [(self.running.pop(future), self._outcome(future)) for future in done]

    @staticmethod
    def _outcome(future) -> Outcome:
        try:
            return future.result()
        except Exception as error:  # e.g. KilledWorker: the case took its worker down
            return Outcome("failed", None, f"{type(error).__name__}: {error}", float("nan"))

    def close(self, completed: bool) -> None:
        if self.running:
            self.client.cancel(list(self.running))
        self.client.close()
