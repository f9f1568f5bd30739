"""A sweep's directory belongs to one study, and one process writes into it at a time.

A sweep, convergence or stability run claims its output directory before it
computes anything:

- the lock: ``DIR/.biostudy.lock``, held with ``fcntl.flock`` for as long as
  the run writes there.  The kernel releases it when the process ends, however
  it ends (SIGKILL included), so a dead run never blocks the next one.  A
  second run into a locked directory is refused at once, naming the process
  that holds it; it never disturbs the first.  Array tasks (``sweep --case``,
  ``--task N --tasks M``) hold it shared: many of them write their own cases
  into one directory at once; a whole sweep into it is refused while they run,
  and they while it runs.
- the owner: ``DIR/.biostudy-owner.toml`` records which study the directory
  belongs to (its kind, name, base scene and swept keys, and their
  fingerprint).  Re-running the same study, with changed values or
  overrides, resumes there; another study is refused unless the user asks
  for it (``--force``), as is a directory that holds files but no owner
  record (a user's folder, or a sweep of an older biostudy).

What makes two runs "the same study" is what they are about, not every
value: the kind of run, its name, its base scene file and the keys it
sweeps.  Changed values make stale cases, which the case fingerprints catch
and run again.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import hashlib
import json
import os
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Iterator

from ..data import store
from ..errors import BadInput
from ..inputs.tomltext import dumps as toml_dumps

LOCK = ".biostudy.lock"
OWNER = ".biostudy-owner.toml"


@dataclass(frozen=True)
class Owner:
    """Which study a directory belongs to."""

    kind: str  # "study", "catalogue", "convergence"
    name: str
    scene: str  # the base scene file, resolved
    keys: tuple[str, ...] = ()  # swept keys

    @property
    def fingerprint(self) -> str:
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()

    def describe(self) -> str:
        keys = f" over {', '.join(self.keys)}" if self.keys else ""
        return f"{self.kind} '{self.name}' of {self.scene}{keys}"


def _recorded(directory: Path) -> dict | None:
    try:
        return tomllib.loads((directory / OWNER).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return {}  # unreadable: as good as a foreign owner


def _lock(directory: Path, shared: bool = False) -> int:
    """Take the directory's lock (without waiting); returns its file descriptor.  `BadInput` if another
    process holds it (`shared`: unless the others hold it shared too, as array tasks do)."""
    fd = os.open(directory / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise BadInput(f"another biostudy run is writing into this directory ({holder}); wait for it to finish "
                       "or stop it, or give another -o", directory) from None
    holder = (f"{'array tasks, the latest ' if shared else ''}pid {os.getpid()} on {os.uname().nodename}, since "
              f"{_dt.datetime.now().isoformat(timespec='seconds')}\n").encode()
    os.pwrite(fd, holder.ljust(200), 0)  # one write of a fixed length: readers never see it half-replaced
    return fd


def _check_owner(directory: Path, owner: Owner, force: bool) -> None:
    recorded = _recorded(directory)
    if recorded is None:  # (the owner record of an array task starting beside this one may be in flight)
        others = [p.name for p in directory.iterdir() if p.name not in (LOCK, OWNER)
                  and not p.name.startswith(f".{OWNER}.")]
        if others and not force:
            raise BadInput(f"holds files that no biostudy run recorded as its own ({', '.join(sorted(others)[:3])}"
                           f"{', ...' if len(others) > 3 else ''}); give --force to use it for {owner.describe()}, "
                           "or give another -o", directory)
    elif recorded.get("fingerprint") != owner.fingerprint and not force:
        theirs = recorded.get("owner", "an unreadable record")
        raise BadInput(f"belongs to {theirs}, not to {owner.describe()}; give --force to take it over (its cases "
                       "of the same ids are then replaced), or give another -o", directory)


@contextlib.contextmanager
def claimed(directory: str | Path, owner: Owner, force: bool = False, shared: bool = False) -> Iterator[Path]:
    """Lock `directory` (created if needed) for this process and make sure it belongs to `owner` (or take
    it over with `force`); held until the block ends.  `shared`: an array task, which shares the directory
    with the other tasks of its study (each writes its own cases) but not with a whole sweep."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd = _lock(directory, shared)
    except FileExistsError:
        raise BadInput("is a file, not a directory", directory) from None
    except OSError as error:
        raise BadInput(f"cannot write here ({error.strerror or error})", directory) from None
    try:
        _check_owner(directory, owner, force)
        record = toml_dumps({"owner": owner.describe(), "fingerprint": owner.fingerprint, **asdict(owner),
                             "keys": list(owner.keys)})
        store.write_text(directory / OWNER, record)
        yield directory
    finally:
        os.close(fd)  # releases the lock
