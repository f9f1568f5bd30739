"""Cases on a Dask cluster (README, "Sweeps on a Dask cluster"), and the choice between it and local workers.

The cluster's workers only simulate: each receives a compiled `solver.Problem`
(plain arrays) and returns the dataset or the reason it failed; this process
writes every file, so the workers need no shared filesystem.  Dask's nanny
starts its workers with one thread per library.  A `tls://` scheduler needs
Dask's TLS configuration (certificates), checked before anything runs.
"""
from __future__ import annotations

import uuid
from typing import TYPE_CHECKING

from ..errors import BadInput
from .worker import Outcome, solve

if TYPE_CHECKING:
    import solver

CONNECT_TIMEOUT = "10s"  # to reach a Dask scheduler


def check_choice(workers: int | None, scheduler: str | None) -> None:
    """Jobs run on local processes or on a Dask cluster, not both; a tls:// scheduler needs Dask's TLS
    configuration (certificates), which a plain Dask client would only miss with a traceback."""
    if workers and scheduler:
        raise BadInput("give --workers or --scheduler, not both", "--workers")
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

    def __init__(self, address: str):
        from distributed import Client

        try:
            self.client = Client(address, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as error:
            raise BadInput(f"cannot connect to a Dask scheduler at {address} ({error})", "--scheduler") from None
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
