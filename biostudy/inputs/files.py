"""Reading the files a user hands in (scenes, studies, masks, tables, scheduler files): one clear line when one
cannot be read.

Every input file is read here, so that what counts as unreadable (missing,
a directory, not text, not TOML) is told the same way everywhere: a
`BadInput` naming the file.  An input file must be a regular file of bounded
size, checked before it is opened: `/dev/zero` would otherwise fill the
memory, and a FIFO block the run forever.  TOML files (scene, study,
catalogue) may hold `TOML_BYTES`, a mask `MASK_BYTES` (a 1000³ boolean grid);
measurement tables and Dask scheduler files have limits of their own where
they are read (`measurements.TABLE_BYTES`, `dask.SCHEDULER_FILE_BYTES`).
"""
from __future__ import annotations

import codecs
import errno
import os
import stat
import tomllib
from pathlib import Path

from ..errors import BadInput, from_toml_error

TOML_BYTES = 16 << 20  # 16 MiB: a study listing a hundred thousand values is ~2 MB
MASK_BYTES = 1 << 30  # 1 GiB


LOOP = "is a symbolic link loop (it leads back to itself)"


def link_loop(path: str | Path) -> bool:
    """Whether `path` (or a directory on the way to it) is a symbolic link leading back to itself: `Path.exists`
    says False for it, as for a missing file, so it would be told as one."""
    try:
        os.stat(path)
    except OSError as error:
        return error.errno == errno.ELOOP
    return False


def no_directory(path: str | Path) -> str:
    """Why `path` cannot be an output directory ('' if it can): a link loop, or a file that is there."""
    if link_loop(path):
        return LOOP
    return "is a file, not a directory" if os.path.lexists(path) and not os.path.isdir(path) else ""


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def size_text(count: int) -> str:
    """Bytes in binary units for limits: '16 MiB', '1 GiB'."""
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if count >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count} bytes"


def checked(path: str | Path, limit: int, what: str) -> os.stat_result:
    """The status of an input file that may be read: a regular file (a link to one is followed) of at most
    `limit` bytes; `what` names it in the one-line `BadInput` otherwise (e.g. "a TOML file")."""
    path = Path(path)
    try:
        found = os.stat(path)
    except FileNotFoundError:
        raise BadInput("no such file", path) from None
    except OSError as error:
        raise BadInput(LOOP if error.errno == errno.ELOOP else f"cannot read: {error.strerror or error}",
                       path) from None
    if not stat.S_ISREG(found.st_mode):
        raise BadInput(f"is {_kind(found.st_mode)}, not {what}", path)
    if found.st_size > limit:
        raise BadInput(f"is {size_text(found.st_size)}; {what} may hold at most {size_text(limit)}", path)
    return found


def read_bytes(path: str | Path, limit: int, what: str) -> bytes:
    """The contents of an input file (`checked`), read without waiting on a FIFO put there after the check and
    never beyond `limit` bytes."""
    checked(path, limit, what)
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        try:
            if not stat.S_ISREG(os.fstat(handle).st_mode):
                raise BadInput(f"is not a regular file, not {what}", path)
            data = _read_all(handle, limit + 1)
        finally:
            os.close(handle)
    except OSError as error:
        raise BadInput(f"cannot read: {error.strerror or error}", path) from None
    if len(data) > limit:
        raise BadInput(f"grew beyond {size_text(limit)} while it was read; {what} may hold at most that", path)
    return data


def _read_all(handle: int, most: int) -> bytes:
    parts, count = [], 0
    while count < most:
        part = os.read(handle, min(1 << 24, most - count))
        if not part:
            break
        parts.append(part)
        count += len(part)
    return b"".join(parts)


def read_text(path: str | Path, limit: int, what: str, spreadsheet: bool = False) -> str:
    """The text of an input file (`read_bytes`); text that is not UTF-8 is `BadInput`.  A `spreadsheet`'s
    export may also begin with a byte-order mark: UTF-8's is dropped, and with UTF-16's (Excel's "Unicode
    text") the file is read as UTF-16."""
    data = read_bytes(path, limit, what)
    encoding = "utf-8-sig" if spreadsheet else "utf-8"
    if spreadsheet and data[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE):
        encoding = "utf-16"
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as error:
        name = "UTF-16" if encoding == "utf-16" else "UTF-8"
        raise BadInput(f"cannot read: not {name} text ({error.reason} at byte {error.start})", path) from None


def read_toml(path: str | Path) -> dict:
    """Parse a TOML file; a missing, unreadable, oversized or malformed file, or one that is no regular file, is
    `BadInput`."""
    path = Path(path)
    text = read_text(path, TOML_BYTES, "a TOML file")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise from_toml_error(error, path) from None
    except RecursionError:  # 'a = [[[[...': tomllib's parser recurses once per level
        raise BadInput("not valid TOML: arrays or tables nested too deeply", path) from None
