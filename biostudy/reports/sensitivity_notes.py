"""What an analysis says in words beside its indices (`sensitivity.analyze`'s `notes`): the cases left out and
what that does to the indices, outputs undefined in some cases, and Sobol' indices estimated from too few samples.

Sobol' indices are shares of an output's variance, in [0, 1], with S1 <= ST; estimated from n base samples
(Saltelli's design, Jansen's estimators: SALib) they are noisy, their bootstrap intervals shrinking as 1/sqrt(n).
At small n an estimate can leave [0, 1] or put S1 above ST (S1 = 1.2 > ST = 0.73 at n = 8): numbers that are no
index of anything.  `sobol_warning` says so when any 95 % half-width exceeds `SOBOL_HALF_WIDTH` (0.1: a share
told within ten points of the variance, the resolution at which "matters" and "does not matter" part) or an
estimate is impossible beyond its interval, and names the n that brings the widest interval to 0.1: n (w / 0.1)²,
up to the next power of 2 (Saltelli's sequences are balanced at powers of 2).  Measured on Ishigami's function:
the widest half-width 0.89 at n = 8 asks for n = 1024, where it is 0.085 (tests/test_analysis.py).
"""
from __future__ import annotations

import math

import numpy as np

from ..formatting import number
from ..plans.designs import Sample
from .cases import Cases

SOBOL_HALF_WIDTH = 0.1


def complete_blocks(design: Sample, ok: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Which cases belong to a base sample (sobol) or trajectory (morris) whose cases are all `ok`: the mask
    over the cases, how many blocks are complete and how many there are."""
    block = design.block()
    count = ok.size // block
    complete = np.zeros(ok.size, dtype=bool)
    whole = ok[: count * block].reshape(count, block).all(axis=1)
    complete[: count * block] = np.repeat(whole, block)
    return complete, int(whole.sum()), count


def sobol_warning(data: dict, names: list[str], params: list[str], blocks: np.ndarray, design: Sample) -> str:
    """'' when every Sobol' index is told within `SOBOL_HALF_WIDTH`, else the sentence (module docstring); `data`
    holds S1, ST and their half-widths, each (time, output, parameter); `blocks` the base samples each used."""
    if design.method != "sobol" or "S1" not in data:
        return ""
    s1, st, s1_conf, st_conf = (np.asarray(data[k]) for k in ("S1", "ST", "S1_conf", "ST_conf"))
    widths = np.fmax(s1_conf, st_conf)
    if not np.isfinite(widths).any():
        return ""
    widest = float(np.nanmax(widths))
    odd = (s1 - st > s1_conf + st_conf) | (s1 < -s1_conf) | (st > 1 + st_conf)
    if widest <= SOBOL_HALF_WIDTH and not odd.any():
        return ""
    n = int(np.max(blocks))
    needed = 2 ** math.ceil(math.log2(max(n * (widest / SOBOL_HALF_WIDTH) ** 2, n + 1)))
    shown = []
    for t, o, p in zip(*np.nonzero(odd)):
        shown.append(f"S1 = {number(s1[t, o, p], 2)}, ST = {number(st[t, o, p], 2)} for {params[p]} ({names[o]})")
    found = f" ({'; '.join(shown[:2])}{'; ...' if len(shown) > 2 else ''}: not possible for indices)" if shown else ""
    return (f"Sobol' indices at n = {n} base samples are not yet estimates{found}: their 95 % intervals reach "
            f"±{number(widest, 2)}; about n = {needed} brings them to ±{number(SOBOL_HALF_WIDTH)} (they shrink as "
            f"1/sqrt(n)): set [sample] n = {needed} and run the sweep again (the cases done are kept).")


def left_out(flat: Cases, design: Sample | None) -> list[str]:
    """What was left out of the analysis and what that does to the indices."""
    notes = [f"{name} is categorical ({', '.join(f'{i} = {label}' for i, label in enumerate(labels))}: coded in "
             f"the order the study lists them); its rank correlations compare the outputs across that order."
             for name, labels in flat.categories.items()]
    status = flat.status
    total = len(status)
    missing = int((status == "missing").sum())
    failed = np.flatnonzero(status == "failed")
    if missing:
        notes.append(f"Unfinished study: {missing} of {total} cases have not run yet; the analysis uses the "
                     f"{int((status == 'done').sum())} that are done.")
    if failed.size:
        spread = "; ".join(f"{p} {number(v[failed].min())}..{number(v[failed].max())}"
                           for p, v in flat.parameters.items())
        listed = ", ".join(flat.ids[i] for i in failed[:5]) + (", ..." if failed.size > 5 else "")
        notes.append(f"{failed.size} of {total} cases failed and are left out ({listed}; their values: {spread}). "
                     f"If failures gather in one part "
                     f"of the ranges, the indices describe the model where it ran, not over the whole ranges.")
    if design is not None and design.method in ("sobol", "morris") and (missing or failed.size):
        block = design.block()
        _, kept, count = complete_blocks(design, status == "done")
        unit = "base samples" if design.method == "sobol" else "trajectories"
        notes.append(f"{design.method}: {count - kept} of {count} {unit} are incomplete and left out "
                     f"whole (each needs all its {block} cases); the indices come from {kept}, so "
                     f"their intervals are about {number(np.sqrt(count / max(kept, 1)), 3)} times "
                     f"as wide as the full design's would be.")
    if not notes:
        notes.append(f"All {total} cases finished.")
    return notes


def undefined(flat: Cases, names, times, used, blocks) -> list[str]:
    """Outputs without a value in some finished cases (a height where no biofilm is dense, say): left out too."""
    done = int((flat.status == "done").sum())
    design = flat.design
    notes = []
    for t, time in enumerate(times):
        for o, name in enumerate(names):
            if used[t, o] == done:
                continue
            when = f" at T* = {number(time)}" if time is not None else ""
            text = (f"{name}{when} has no value in {done - used[t, o]} of {done} finished cases (it is undefined "
                    f"there) and they are left out")
            if design is not None and design.method in ("sobol", "morris"):
                text += f"; its indices come from {blocks[t, o]} complete blocks"
            notes.append(text + ".")
    return notes
