"""The `biostudy` command line: `app` is the typer application (README's command table)."""
from .app import app

__all__ = ["app"]
