"""The `biostudy` command line: `app` is the typer application (README's command table).

A command's process ends without the garbage collector's passes over every
object the libraries it imported made (FiPy, xarray, dask): at exit they are
frozen (`gc.freeze`), and the interpreter's exit after the result is written
takes a tenth of the time (benchmarks/time_left.py: the "exit" column).
Nothing is lost: Python does not promise to finalise the objects still alive
at exit, and every file a command writes is closed before it returns.
"""
import atexit
import gc

from .app import app

atexit.register(gc.freeze)  # at exit, before the interpreter's own collections, which then skip what is frozen

__all__ = ["app"]
