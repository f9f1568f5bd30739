"""One benchmark case in a fresh process, so that its peak memory is its own: shared by the mechanics benchmarks."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys


def run_case(script: str, arguments: list[str], baseline: str | None = None, timeout: float | None = None) -> dict:
    """Run `script arguments` (it prints one JSON line last) under /usr/bin/time -v when that is there.

    baseline: a directory put first on PYTHONPATH (another version's solver/ and biostudy/).
    Returns the JSON plus peak_gb and the load average at the start, or {"error": ..., "load": ...}."""
    command = [sys.executable, os.path.abspath(script), *arguments]
    timer = shutil.which("time") or ("/usr/bin/time" if os.path.exists("/usr/bin/time") else None)
    if timer:
        command = [timer, "-v", *command]
    env = dict(os.environ)
    if baseline:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [os.path.abspath(baseline), env.get("PYTHONPATH")]))
    load = os.getloadavg()[0]
    # a session of its own: on timeout the case is killed with /usr/bin/time, not left running as an orphan
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                          start_new_session=True) as process:
        try:
            stdout, stderr = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
            return {"error": f"stopped after {timeout:.0f} s", "load": load}
    if process.returncode != 0:
        lines = stderr.strip().splitlines()
        last = next((line for line in reversed(lines) if not line.startswith("\t")), "failed")
        return {"error": last[:100], "load": load}
    result = json.loads(stdout.strip().splitlines()[-1])
    peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", stderr)
    result["peak_gb"] = int(peak.group(1)) / 1024**2 if peak else float("nan")
    result["load"] = load
    return result


def header(text: str):
    print(text)
    print("-" * len(text))
