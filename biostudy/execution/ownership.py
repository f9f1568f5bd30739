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

A run that is refused (bad input found after the claim: a foreign file, a
scheduler that cannot be reached, too little memory) leaves the directory as
it found it: what the claim made (the directory, its lock file, its owner
record, an empty ``cases/``) is removed again, and an owner record it
replaced is put back.
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
from typing import Callable, Iterator

from ..data import writing
from ..errors import BadInput
from ..inputs.files import no_directory
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
    process holds it (`shared`: unless the others hold it shared too, as array tasks do).  A lock file
    removed by a refused run while this one opened it is not a lock: the lock is taken again on the file
    that is there."""
    path = directory / LOCK
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)  # as every output: the umask decides who may lock
        try:
            fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
            os.close(fd)
            raise BadInput(f"another biostudy run is writing into this directory ({holder}); wait for it to finish "
                           "or stop it, or give another -o", directory) from None
        try:
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    holder = (f"{'array tasks, the latest ' if shared else ''}pid {os.getpid()} on {os.uname().nodename}, since "
              f"{_dt.datetime.now().isoformat(timespec='seconds')}\n").encode()
    os.pwrite(fd, holder.ljust(200), 0)  # one write of a fixed length: readers never see it half-replaced
    return fd


def _check_owner(directory: Path, owner: Owner, force: bool, recorded: dict | None) -> None:
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


def _missing(directory: Path) -> list[Path]:
    """`directory` and those of its parents that do not exist yet, deepest first."""
    missing = []
    while not directory.exists() and directory != directory.parent:
        missing.append(directory)
        directory = directory.parent
    return missing


def _read(path: Path) -> bytes | None:
    try:
        return path.read_bytes()
    except OSError:
        return None


@contextlib.contextmanager
def claimed(directory: str | Path, owner: Owner, force: bool = False,
            check: Callable[[Path, bool], None] | None = None, shared: bool = False) -> Iterator[Path]:
    """Lock `directory` (created if needed) for this process and make sure it belongs to `owner` (or take
    it over with `force`); held until the block ends.  `shared`: an array task, which shares the directory
    with the other tasks of its study (each writes its own cases) but not with a whole sweep.
    check(directory, biostudy's) runs before the owner
    record is written, told whether a biostudy run owned the directory before (so its damaged files are
    biostudy's).  `BadInput` from the claim, the check or the block (before it recorded a case) leaves the
    directory as it was found."""
    directory = Path(directory)
    made = _missing(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        had = {name: (directory / name).exists() for name in (LOCK, "cases")}
        previous = _read(directory / OWNER)
        cases = _names(directory / "cases")
        fd = _lock(directory, shared)
    except FileExistsError:
        raise BadInput(no_directory(directory) or "is a file, not a directory", directory) from None
    except OSError as error:
        raise BadInput(f"cannot write here ({error.strerror or error})", directory) from None
    except BadInput:
        _remove_empty(made)
        raise
    try:
        recorded = _recorded(directory)
        _check_owner(directory, owner, force, recorded)
        if check is not None:
            check(directory, bool(recorded and "fingerprint" in recorded))
        record = toml_dumps({"owner": owner.describe(), "fingerprint": owner.fingerprint, **asdict(owner),
                             "keys": list(owner.keys)})
        writing.write_text(directory / OWNER, record)
        yield directory
    except BadInput:  # refused: the directory as it was found, unless cases were recorded meanwhile
        if _names(directory / "cases") - cases:
            raise
        if previous is None:
            (directory / OWNER).unlink(missing_ok=True)
        else:
            writing.atomic(directory / OWNER, lambda temporary: temporary.write_bytes(previous))
        if not had["cases"]:
            _remove_empty([directory / "cases"])
        if not had[LOCK] and not shared:  # (array tasks beside this one may hold it too)
            (directory / LOCK).unlink(missing_ok=True)  # still held: no one else has it open and locked
        _remove_empty(made)
        raise
    finally:
        os.close(fd)  # releases the lock


def _names(directory: Path) -> set[str]:
    try:
        return {p.name for p in directory.iterdir()}
    except OSError:
        return set()


def _remove_empty(directories: list[Path]) -> None:
    for directory in directories:
        with contextlib.suppress(OSError):
            directory.rmdir()
