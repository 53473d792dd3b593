"""A segment's state at many times at once, with numpy (the single slider's ``sample``).

The closed forms of :mod:`friction_sim.core.physics.segment`, evaluated on
arrays: numpy's sin is within an ulp or two of libm's, so a sampled state may
differ from the scalar one at the same time in its last bits.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from friction_sim.core.physics.plant import Plant
from friction_sim.core.physics.roots import remainders_many
from friction_sim.core.physics.segment import FLIGHT, STUCK, x_axis, z_axis
from friction_sim.core.physics.transient import transient_evaluate


def _axis_many(h: Any, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(w, start + integral of w, dw/dt) of a Harmonic at an array of times."""
    c1, s2, c2 = remainders_many(h.omega * tau)
    w = h.w0 + h.g0 * tau + h.k * (h.cos0 * c1 - h.sin0 * s2)
    moved = h.start + (h.w0 * tau + 0.5 * h.g0 * tau * tau + h.kk * (h.cos0 * s2 - h.sin0 * c2))
    return w, moved, h.b0 + h.b1 * np.sin(h.phase0 + h.omega * tau)


def evaluate_many(p: Plant, mode: int, x0: float, xl: float, v0: float, vz0: float, z0: float, phase0: float,
                  tau: np.ndarray, c: complex = 0j, lam: complex = 0j) -> tuple[np.ndarray, ...]:
    """:func:`~friction_sim.core.physics.segment.evaluate` at an array of times (numpy's
    sin: within an ulp or two of libm's, so a sampled state may differ from
    :meth:`~friction_sim.core.engine.single.Slider.state` at the same time in its last bits).
    Under the exciter's transient force Re(``c``*exp(``lam``*tau)) the states are
    :func:`~friction_sim.core.physics.transient.transient_evaluate`'s, one by one."""
    if c:
        rows = [transient_evaluate(p, mode, x0, xl, v0, vz0, z0, phase0, c, lam, float(each)) for each in tau]
        return tuple(np.array(column, dtype=float) for column in zip(*rows))
    theta = phase0 + p.omega * tau
    zero = tau * 0.0
    if mode == FLIGHT:
        v, moved, rate = _axis_many(x_axis(p, mode, v0, phase0), tau)
        vz, z, _ = _axis_many(z_axis(p, phase0, vz0, z0), tau)
        return x0 + (xl + moved), v, rate, zero, zero, theta, z, vz
    sin_theta = np.sin(theta)
    if p.kostek:
        normal = p.n0 - p.pa * sin_theta
        if mode == STUCK:
            return x0 + zero, zero, zero, -p.tangential.b0 + zero, normal, theta, zero, zero
        h = x_axis(p, mode, v0, phase0)
        w, moved, _ = _axis_many(h, tau)
        return (x0 + (xl + mode * moved), mode * w, mode * (h.b0 + h.b1 * sin_theta), -mode * p.mu * normal,
                normal, theta, zero, zero)
    normal = (p.n0 - p.pa * (sin_theta if p.lag == 0.0 else np.sin(theta - p.lag))) if p.pa else p.n0 + zero
    if mode == STUCK:
        force = p.tangential.b0 + p.tangential.b1 * np.sin(theta + p.tangential.delta)
        return x0 + zero, zero, zero, -force, normal, theta, zero, zero
    w, moved, rate = _axis_many(x_axis(p, mode, v0, phase0), tau)
    return (x0 + (xl + mode * moved), mode * w, mode * rate, -mode * p.mu * normal, normal, theta, zero,
            zero)


__all__ = ["evaluate_many"]
