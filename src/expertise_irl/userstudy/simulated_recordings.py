"""Cartesian recordings of simulated people (``expertise-irl simulate-recordings``).

A simulated person (:func:`~expertise_irl.demos.simulation.simulate`) chooses moves on the floor plan;
a robot then drives that path in continuous space and is sampled like a tele-operated
robot's odometry:

- it drives from cell centre to cell centre in straight lines at ``speed`` m/s, waiting
  ``dwell_s`` seconds at the start and on the goal;
- after arriving at a cell it pauses with probability ``pause_prob`` for a time drawn
  uniformly from [0.5, 1.5] × ``pause_s`` seconds;
- its position is sampled at ``hz`` samples per second (t = k / hz from 0), each sample
  displaced by independent Gaussian noise of ``noise`` metres per axis;
- ``gaps`` stretches of ``gap_s`` seconds lose their samples (each in a random episode,
  starting at a uniform time at least ``gap_s`` from the episode's ends), as a logger
  that drops out would.

At 1 Hz resampling a robot faster than one cell per second skips cells, which ingestion
reports as gaps; the default speed, 0.8 cells per second, never does. Noise beyond about a
quarter of a cell puts samples in the wrong cell (extra moves) or in obstacles (use
``--snap``). All randomness comes from one generator: the same seed gives the same file.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..demos.simulation import simulate
from ..demos.trajectories import Trajectories
from ..errors import InputError
from ..worlds.warehouse import WarehouseMap


@dataclass(frozen=True)
class RobotMotion:
    """How the simulated robot drives and is recorded (see the module docstring)."""

    hz: float = 10.0
    speed: float | None = None  # m/s; default 0.8 cells per second
    noise: float = 0.03
    pause_prob: float = 0.05
    pause_s: float = 2.0
    dwell_s: float = 1.0
    gaps: int = 0
    gap_s: float = 3.0

    def check(self, plan: WarehouseMap) -> None:
        for name, v, lo in (
            ("--hz", self.hz, 0.0),
            ("--speed", self.speed_of(plan), 0.0),
            ("--pause-s", self.pause_s, -1e-300),
            ("--gap-s", self.gap_s, 0.0),
        ):
            if not (math.isfinite(v) and v > lo):
                raise InputError(f"{name} must be a finite number > {max(lo, 0):g}, got {v:g}")
        if not (math.isfinite(self.noise) and self.noise >= 0):
            raise InputError(f"--noise must be a number of metres >= 0, got {self.noise:g}")
        if not 0 <= self.pause_prob <= 1:
            raise InputError(f"--pause-prob must be a probability in [0, 1], got {self.pause_prob:g}")
        if self.gaps < 0:
            raise InputError(f"--gaps must be >= 0, got {self.gaps}")

    def speed_of(self, plan: WarehouseMap) -> float:
        return 0.8 * plan.cell_size if self.speed is None else float(self.speed)


def _knots(plan: WarehouseMap, cells: np.ndarray, motion: RobotMotion, rng: np.random.Generator):
    """Times and (x, y) of the robot's corners: it is at ``xy[i]`` from ``t[2i]`` to ``t[2i+1]``."""
    x, y = plan.centre_of(cells[:, 0], cells[:, 1])
    leg = plan.cell_size / motion.speed_of(plan)
    t, pts = [], []
    now = 0.0
    for i in range(len(cells)):
        if i == 0 or i == len(cells) - 1:
            wait = motion.dwell_s
        else:
            wait = rng.uniform(0.5, 1.5) * motion.pause_s if rng.random() < motion.pause_prob else 0.0
        t += [now, now + wait]
        pts += [(x[i], y[i]), (x[i], y[i])]
        now += wait + leg
    return np.array(t), np.array(pts)


def episode_samples(
    plan: WarehouseMap, cells: np.ndarray, motion: RobotMotion, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, x, y)`` of one episode driven through ``cells`` (``[T, 2]`` col, row)."""
    kt, kp = _knots(plan, cells, motion, rng)
    n = math.floor(kt[-1] * motion.hz + 1e-9) + 1
    t = np.arange(n) / motion.hz
    x = np.interp(t, kt, kp[:, 0]) + rng.normal(0.0, motion.noise, n)
    y = np.interp(t, kt, kp[:, 1]) + rng.normal(0.0, motion.noise, n)
    return t, x, y


def simulate_recordings(
    plan: WarehouseMap,
    theta,
    beta: float,
    episodes: int,
    rng: np.random.Generator,
    *,
    motion: RobotMotion = RobotMotion(),
    max_steps: int = 500,
    model: str = "maxent",
) -> tuple[list[tuple[int, np.ndarray, np.ndarray, np.ndarray]], Trajectories]:
    """Episodes of a simulated person on ``plan`` and their recordings.

    Returns ``([(episode, t, x, y), ...], trajectories)``: the samples of each episode (after
    the gaps are cut out) and the moves the person chose.
    """
    motion.check(plan)
    mdp = plan.to_mdp()
    trajs = simulate(mdp, theta, beta, episodes, rng, max_steps=max_steps, model=model)
    cells_of = plan.state_cells()
    out = []
    for e, (s, a) in zip(trajs.episode_ids.tolist(), trajs.episodes(), strict=True):
        path = np.append(s, mdp.next_state[s[-1], a[-1]])
        t, x, y = episode_samples(plan, cells_of[path], motion, rng)
        out.append([int(e), t, x, y])
    for _ in range(motion.gaps):
        ok = [i for i, (_, t, _, _) in enumerate(out) if t[-1] > 3 * motion.gap_s]
        if not ok:
            raise InputError(f"--gaps: no episode is longer than 3 × --gap-s = {3 * motion.gap_s:g} s")
        i = int(rng.choice(ok))
        e, t, x, y = out[i]
        start = rng.uniform(motion.gap_s, t[-1] - 2 * motion.gap_s)
        keep = (t < start) | (t >= start + motion.gap_s)
        out[i] = [e, t[keep], x[keep], y[keep]]
    return [tuple(r) for r in out], trajs


def write_recording(path: str | Path, episodes) -> int:
    """Write ``episode,t,x,y`` (t to the millisecond, x and y to 0.1 mm); returns the rows written."""
    n = 0
    with open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["episode", "t", "x", "y"])
        for e, t, x, y in episodes:
            for ti, xi, yi in zip(t.tolist(), x.tolist(), y.tolist(), strict=True):
                w.writerow([e, f"{ti:.3f}", f"{xi:.4f}", f"{yi:.4f}"])
                n += 1
    return n
