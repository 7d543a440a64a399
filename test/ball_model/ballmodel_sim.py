"""Independent ball simulation for the tests: explicit Euler of the two-phase deceleration.

Deliberately shares no code with erforce_ball_model (no closed forms): a velocity vector is
stepped at 0.1 ms, with the deceleration chosen from the current speed versus the kick speed.
"""

from __future__ import annotations

import numpy as np

DT_SIM = 1e-4


def simulate(events, t_end, a_slide=2.5, a_roll=0.3, c_switch=0.6, p0=(0.0, 0.0)):
    """Ball path with velocity ``events`` [(t, (vx, vy)), ...] applied (kicks or reflections).

    Every event restarts the sliding phase with v_shoot = new speed. Returns (t, pos, vel) arrays.
    """
    n = int(np.ceil(t_end / DT_SIM)) + 1
    t = np.arange(n) * DT_SIM
    pos = np.zeros((n, 2))
    vel = np.zeros((n, 2))
    p = np.array(p0, dtype=float)
    v = np.zeros(2)
    v_shoot = 0.0
    queue = sorted(events, key=lambda e: e[0])
    k = 0
    for i in range(n):
        while k < len(queue) and queue[k][0] <= t[i]:
            v = np.array(queue[k][1], dtype=float)
            v_shoot = float(np.hypot(*v))
            k += 1
        pos[i], vel[i] = p, v
        s = float(np.hypot(*v))
        if s > 0.0:
            a = a_slide if s > c_switch * v_shoot else a_roll
            s_new = max(s - a * DT_SIM, 0.0)
            v_new = v * (s_new / s)
            p = p + 0.5 * (v + v_new) * DT_SIM
            v = v_new
    return t, pos, vel


def observe(t, pos, fps=70.0, noise_m=0.002, dropout=0.1, seed=0, t_start=0.0):
    """Vision frames of a simulated path: (frame times, noisy xy, index into the path)."""
    rng = np.random.default_rng(seed)
    frames = np.arange(t_start + rng.uniform(0.0, 1.0 / fps), t[-1], 1.0 / fps)
    frames = frames[rng.random(frames.size) >= dropout]
    idx = np.minimum(np.searchsorted(t, frames), t.size - 1)
    xy = pos[idx] + rng.normal(0.0, noise_m, (idx.size, 2))
    return t[idx], xy, idx
