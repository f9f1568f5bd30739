"""The command line's process ends without collecting the objects its libraries made (`biostudy.cli`)."""
from __future__ import annotations

import subprocess
import sys


def test_the_collector_is_frozen_at_exit():
    """An exit handler registered before biostudy.cli is imported runs after biostudy's: by then every object is
    frozen, and the interpreter's own collections at exit pass over none of them."""
    code = ("import atexit, gc; atexit.register(lambda: print(gc.get_freeze_count())); import biostudy.cli; "
            "print(gc.get_freeze_count())")
    ran = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    before, at_exit = map(int, ran.stdout.split())
    assert before == 0 and at_exit > 10_000
