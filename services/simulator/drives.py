"""The motor drives and belts, per axis: first-order speed lag, constant-speed moves, backlash.

Pure functions on arrays of motor (encoder) angles [deg] and speeds [deg/s]; the same
functions serve the gripper in [mm] and [mm/s]. Integration is in closed form, so one call
per 20 ms tick is exact whatever the time constant.
"""

from __future__ import annotations

import math

import numpy as np


def lag_step(
    x: np.ndarray, v: np.ndarray, u: np.ndarray, dt_s: float, tau_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Exact integration of a first-order speed lag over ``dt_s``.

    The speed obeys dv/dt = (u - v) / tau with the target ``u`` constant over the step, so
    v(t) = u + (v0 - u) e^(-t/tau) and x(t) = x0 + u t + (v0 - u) tau (1 - e^(-t/tau)).

    Args:
        x: positions at the start of the step, shape (n,) [deg or mm].
        v: speeds at the start of the step, shape (n,) [deg/s or mm/s].
        u: target speeds held over the step, shape (n,) [deg/s or mm/s].
        dt_s: step length [s], >= 0.
        tau_s: time constant [s]; 0 means the speed jumps to ``u`` at once.

    Returns:
        (positions, speeds) at the end of the step, each shape (n,).
    """
    if tau_s <= 0.0:
        return x + u * dt_s, u.copy()
    a = math.exp(-dt_s / tau_s)
    dv = v - u
    return x + u * dt_s + dv * (tau_s * (1.0 - a)), u + dv * a


def move_toward(
    x: np.ndarray, target: np.ndarray, rates: np.ndarray, dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Constant-speed motion toward ``target``, stopping on it (the fold procedures).

    Args:
        x: positions, shape (n,) [deg].
        target: where each axis stops, shape (n,) [deg].
        rates: speed magnitude of each axis, shape (n,) [deg/s], >= 0.
        dt_s: step length [s], > 0.

    Returns:
        (positions, mean speeds over the step) at the end of the step.
    """
    step = np.clip(target - x, -rates * dt_s, rates * dt_s)
    new = x + step
    return new, step / dt_s if dt_s > 0 else np.zeros_like(x)


def backlash(output: np.ndarray, drive: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Output side of a transmission with play (dead band) of full ``width``.

    The output stays where it is while the drive moves inside the slack and is dragged
    along once the drive has taken it up: |drive - output| <= width / 2 always.

    Args:
        output: output positions before the drive moved, shape (n,) [deg].
        drive: drive (motor) positions now, shape (n,) [deg].
        width: full dead band of each axis, shape (n,) [deg], >= 0.
    """
    half = width / 2.0
    return np.asarray(np.clip(output, drive - half, drive + half))
