"""Reading the files a user hands in (scene, study, catalogue files): one clear line when one cannot be read.

Every input file is read here, so that what counts as unreadable (missing,
a directory, not text, not TOML) is told the same way everywhere: a
`BadInput` naming the file.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

from ..errors import BadInput, from_toml_error


def read_toml(path: str | Path) -> dict:
    """Parse a TOML file; a missing, unreadable or malformed file is `BadInput`."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BadInput("no such file", path) from None
    except IsADirectoryError:
        raise BadInput("is a directory, not a TOML file", path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise BadInput(f"cannot read: {error}", path) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise from_toml_error(error, path) from None
