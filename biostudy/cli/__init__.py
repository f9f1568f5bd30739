"""The `biostudy` command line: `app` is the typer application (README, "Commands")."""
from .app import app

__all__ = ["app"]
