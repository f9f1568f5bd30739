"""The vector updates of the Krylov solvers, fused and split in blocks over a team.

Each kernel does in one pass what the numpy expression in its docstring does in several, entry by entry
with the same operations in the same order (numba contracts no multiply-add unless asked, and nothing here
asks), so the result is numpy's bit for bit whatever the team.  Sums over a whole vector (dot products and
norms) are not here: they stay numpy's (one BLAS thread), so that they round as before.
"""
from __future__ import annotations

import numba

from .rows import split
from .team import Team

jit = numba.njit(cache=True, nogil=True)


def cg_step(team: Team, x, r, p, q, step: float) -> None:
    """x += step * p; r -= step * q."""
    split(team, x.size, lambda a, b: _cg_step(x, r, p, q, step, a, b))


def cg_direction(team: Team, p, z, beta: float) -> None:
    """p *= beta; p += z."""
    split(team, p.size, lambda a, b: _cg_direction(p, z, beta, a, b))


def bicgstab_direction(team: Team, p, p_hat, r, v, inverse, factor: float, omega: float) -> None:
    """p = r + factor * (p - omega * v); p_hat = inverse * p (in place)."""
    split(team, p.size, lambda a, b: _bicgstab_direction(p, p_hat, r, v, inverse, factor, omega, a, b))


def bicgstab_half(team: Team, s, s_hat, r, v, inverse, alpha: float) -> None:
    """s = r - alpha * v; s_hat = inverse * s (in place)."""
    split(team, s.size, lambda a, b: _bicgstab_half(s, s_hat, r, v, inverse, alpha, a, b))


def bicgstab_step(team: Team, x, r, s, t, p_hat, s_hat, alpha: float, omega: float) -> None:
    """x += alpha * p_hat + omega * s_hat; r = s - omega * t (in place)."""
    split(team, x.size, lambda a, b: _bicgstab_step(x, r, s, t, p_hat, s_hat, alpha, omega, a, b))


def add_scaled(team: Team, x, alpha: float, p) -> None:
    """x += alpha * p."""
    split(team, x.size, lambda a, b: _add_scaled(x, alpha, p, a, b))


@jit
def _cg_step(x, r, p, q, step, start, stop):
    for i in range(start, stop):
        x[i] = x[i] + step * p[i]
        r[i] = r[i] - step * q[i]


@jit
def _cg_direction(p, z, beta, start, stop):
    for i in range(start, stop):
        p[i] = p[i] * beta + z[i]


@jit
def _bicgstab_direction(p, p_hat, r, v, inverse, factor, omega, start, stop):
    for i in range(start, stop):
        p[i] = r[i] + factor * (p[i] - omega * v[i])
        p_hat[i] = inverse[i] * p[i]


@jit
def _bicgstab_half(s, s_hat, r, v, inverse, alpha, start, stop):
    for i in range(start, stop):
        s[i] = r[i] - alpha * v[i]
        s_hat[i] = inverse[i] * s[i]


@jit
def _bicgstab_step(x, r, s, t, p_hat, s_hat, alpha, omega, start, stop):
    for i in range(start, stop):
        x[i] = x[i] + (alpha * p_hat[i] + omega * s_hat[i])
        r[i] = s[i] - omega * t[i]


@jit
def _add_scaled(x, alpha, p, start, stop):
    for i in range(start, stop):
        x[i] = x[i] + alpha * p[i]

