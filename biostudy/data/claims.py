"""Outputs claimed by one writer, and files told apart as biostudy's.

A `Claim` reserves one run's output (`claim`) from before it computes until
its result is written: its temporary (`writing.temporary_name`) is made at
once and tells other biostudy runs that the output is being computed; the
result is renamed over the output only if the output is still the file it
was when claimed, so a result is never silently replaced by another written
meanwhile.  Every report, picture and ParaView file biostudy writes carries a
`mark` (in its metadata or a comment); `foreign` refuses to replace a file of
the same name without it.

The mark travels inside the file (a PNG's Software text chunk, an HTML
comment closing a Markdown report, an XML comment in a VTU), not in a record
beside it: it survives copying and moving a folder, needs no bookkeeping
that a crash or a user's edit could leave out of step, and holds for a
picture written anywhere (`plot -o`), not only in a directory a run owns.
A file that cannot carry a mark (PEtab's simulation.tsv: a TSV whose readers
take every line for a row) is proven by a digest instead: the dataset written
with it records its sha256 (`digested`), and it is replaced only while its
bytes are those (`write_digested`); a user's edit makes it the user's.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import threading
import weakref
from pathlib import Path
from typing import Iterable

from ..errors import BadInput, Failed
from .provenance import version
from .writing import remove_temporaries, temporaries, temporary_name, write_atomic, write_text

HELD: set[Path] = set()  # outputs claimed in this process: its threads share its pid, which the temporary names
HOLDING = threading.Lock()


def mark() -> str:
    """What every picture and ParaView file biostudy writes carries (in its metadata or a comment), so that it
    can tell its own files from others' before replacing one."""
    return f"written by biostudy {version()}"


HEAD = 4096  # bytes at the start of a file where a VTK file's mark stands (its first comment), whatever its size


def marked(path: str | Path, most: int = 1 << 25) -> bool:
    """Whether a file (a picture, a VTK file) carries biostudy's `mark`: in its first `HEAD` bytes, or anywhere in
    a file of at most `most` bytes."""
    path = Path(path)
    try:
        if not path.is_file():
            return False
        with open(path, "rb") as handle:
            if b"written by biostudy " in handle.read(HEAD):
                return True
        return path.stat().st_size <= most and b"written by biostudy " in path.read_bytes()
    except OSError:
        return False


def unproven(paths: Iterable[str | Path], what: str) -> list[BadInput]:
    """A `BadInput` for each of `paths` that exists and does not carry biostudy's `mark`, --force or not."""
    return [BadInput(f"exists and is not {what} biostudy wrote; refusing to overwrite it (choose another "
                     "output, or remove the file first)", path) for path in paths
            if Path(path).exists() and not marked(path)]


def foreign(paths: Iterable[str | Path], what: str) -> None:
    """`BadInput` (every one at once) for those of `paths` that exist and do not carry biostudy's `mark`: a
    file biostudy cannot prove it wrote is never replaced."""
    found = unproven(paths, what)
    if found:
        raise BadInput.every(found)


def write_report(path: str | Path, text: str) -> Path:
    """A Markdown report, written atomically and closed by biostudy's `mark` in an HTML comment (not shown where
    Markdown is rendered); refused (`foreign`) where a file biostudy cannot prove it wrote is."""
    foreign([path], "a report")
    return write_text(path, f"{text.rstrip()}\n\n<!-- {mark()} -->\n")


def _digest_attribute(name: str) -> str:
    return f"{name.replace('.', '_')}_sha256"  # simulation.tsv -> simulation_tsv_sha256


def sha256(path: str | Path) -> str | None:
    """The sha256 of a file's bytes, None if there is no regular file there or it cannot be read."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
    except OSError:  # absent, a directory, unreadable
        return None
    return digest.hexdigest()


def digested(name: str, text: str, replaced: str = "") -> dict[str, str]:
    """The attributes a dataset written with the text file `name` records of it: the sha256 of `text`, and
    that of the file of the same name it replaces (`replaced`, a digest already proven; "" if none), so that a
    run stopped between writing the dataset and the file still proves the file it left."""
    attribute = _digest_attribute(name)
    return {attribute: hashlib.sha256(text.encode("utf-8")).hexdigest(), f"{attribute}_replaced": replaced}


def recorded(attrs: dict | None, name: str) -> set[str]:
    """The digests of file `name` a dataset's attributes record (`digested`; none for a dataset without)."""
    attribute = _digest_attribute(name)
    return {str(attrs[key]) for key in (attribute, f"{attribute}_replaced") if attrs and attrs.get(key)}


def undigested(paths: Iterable[str | Path], attrs: dict | None, summary: str) -> list[BadInput]:
    """A `BadInput` for each of `paths` that exists and whose sha256 the `summary` file's attributes (`attrs`)
    do not record, --force or not."""
    return [BadInput(f"exists and is not a file biostudy wrote (its sha256 is not one {summary} records); "
                     "refusing to overwrite it (choose another output, or remove the file first)", path)
            for path in paths if os.path.lexists(path) and sha256(path) not in recorded(attrs, Path(path).name)]


def write_digested(path: str | Path, text: str, attrs: dict | None, summary: str) -> Path:
    """A text file that cannot carry the `mark`, written atomically; refused (`undigested`) where a file is
    whose sha256 `attrs` (the summary's before this run replaced it) do not record."""
    found = undigested([path], attrs, summary)
    if found:
        raise found[0]
    return write_text(path, text)


def _identity(path: Path) -> tuple | None:
    """What tells a file from its replacement: device, inode, size, modification time (None: no file)."""
    try:
        found = os.stat(path)
    except FileNotFoundError:
        return None
    return found.st_dev, found.st_ino, found.st_size, found.st_mtime_ns


@contextlib.contextmanager
def _directory_locked(directory: Path):
    """This process alone looks at and renames files in `directory` for the block (a brief flock on the
    directory itself; where the file system has no such locks, the block runs unlocked)."""
    handle = os.open(directory, os.O_RDONLY)
    try:
        with contextlib.suppress(OSError):
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield
    finally:
        os.close(handle)  # releases the lock


class Claim:
    """An output reserved for one run until its result is written (`claim`).

    Its temporary (`temporary_name`) is made at once and tells other biostudy runs that the output is being
    computed; the result is written into it and renamed over the output only if the output is still what it
    was when claimed (`replace`), so a result is never silently replaced by another written meanwhile."""

    def __init__(self, target: Path, temporary: Path, removed: list[Path], made: list[Path], held: Path):
        self.target, self.temporary, self.removed = target, temporary, removed
        self.seen = _identity(target)
        self._release = weakref.finalize(self, _give_up, temporary, made, held)

    def write_dataset(self, ds) -> Path:
        """The result, written into the claimed output (`writing.write_atomic`, renamed by `replace`)."""
        return write_atomic(ds, self.target, self.temporary, self.replace)

    def release(self) -> None:
        """Give the output up: the temporary goes, and the directories made for it if nothing was written there;
        a written result stays."""
        self._release()

    def replace(self) -> None:
        """Rename the written temporary over the output, unless the output changed since it was claimed: then
        the result is kept beside it under a new name and `Failed` says where."""
        with _directory_locked(self.target.parent):
            if _identity(self.target) == self.seen:
                os.replace(self.temporary, self.target)
                return
            for number in range(1, 1000):  # a name nothing has: link() never replaces a file
                kept = self.target.with_name(f"{self.target.stem}.{number}{self.target.suffix}")
                with contextlib.suppress(FileExistsError):
                    os.link(self.temporary, kept)
                    break
            self.temporary.unlink()
        raise Failed(f"{self.target} was changed by another program while this run computed; it is left as it "
                     f"is, and this run's result is kept in {kept}")


def _give_up(temporary: Path | None, made: list[Path], held: Path | None = None) -> None:
    """Remove a claim's temporary and the directories made for it (deepest first; one that holds anything
    stays), and let this process claim its output again."""
    if temporary is not None:
        temporary.unlink(missing_ok=True)
    if held is not None:
        with HOLDING:
            HELD.discard(held)
    for directory in made:
        with contextlib.suppress(OSError):
            directory.rmdir()


def claim(path: str | Path) -> Claim:
    """Reserve `path` for this process's result: `BadInput` if another running process, or another thread of
    this one, claimed it (its temporary is there, or `HELD` has it); the temporaries of writers that are gone
    (killed, even with SIGKILL) are removed."""
    path = Path(path)
    made = []
    ancestor = path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        made.append(ancestor)
        ancestor = ancestor.parent
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with _directory_locked(path.parent):
            removed = remove_temporaries(path.parent, of=path.name)
            running = sorted(pid for _, pid in temporaries(path.parent, path.name) if pid != os.getpid())
            held = path.parent.resolve() / path.name
            with HOLDING:
                if held in HELD:
                    running = [os.getpid()]
                elif not running:
                    HELD.add(held)
            if running:
                _give_up(None, made)
                who = f"pid {running[0]}" + (", another thread of this process" if running[0] == os.getpid() else "")
                raise BadInput(f"another biostudy run ({who}) is computing this output; wait for it to end, or "
                               "choose another output", path)
            claim = Claim(path, temporary_name(path), removed, made, held)
            os.close(os.open(claim.temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # the umask decides
    except OSError as error:
        _give_up(None, made)
        raise BadInput(f"cannot write here ({error.strerror or error})", path) from None
    return claim
