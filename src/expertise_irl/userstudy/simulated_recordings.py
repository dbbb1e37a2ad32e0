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

:func:`write_recording` writes the CSV ``episode,t,x,y``, or, by the file's suffix, a ROS bag
holding the same samples (:func:`write_bag`).
"""

from __future__ import annotations

import csv
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_open, atomic_path
from ..demos.rosbag import BAG_SUFFIXES
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
    """Write ``episode,t,x,y`` (t to the millisecond, x and y to 0.1 mm), or a ROS bag if the name ends
    in ``.bag``, ``.db3`` or ``.mcap`` (:func:`write_bag`); returns the rows (messages) written."""
    if Path(path).suffix in BAG_SUFFIXES:
        return write_bag(path, episodes)
    n = 0
    with atomic_open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["episode", "t", "x", "y"])
        for e, t, x, y in episodes:
            for ti, xi, yi in zip(t.tolist(), x.tolist(), y.tolist(), strict=True):
                w.writerow([e, f"{ti:.3f}", f"{xi:.4f}", f"{yi:.4f}"])
                n += 1
    return n


#: The header stamp of a simulated bag's first sample (2024-01-01 00:00 UTC), and the seconds between
#: one episode's last sample and the next one's first.
BAG_START_S = 1_704_067_200
BAG_EPISODE_PAUSE_S = 5.0


def write_bag(path: str | Path, episodes, *, topic: str = "/odom", episode_topic: str = "/episode") -> int:
    """Write the episodes as a ROS bag of the robot's odometry, one file by the suffix: a ROS 1
    ``.bag`` (Noetic's message types) or a ROS 2 ``.db3`` or ``.mcap`` (Humble's; the storage
    file alone, which ``rosbags`` and ``discretise`` read without its folder).

    Each sample is a ``nav_msgs/msg/Odometry`` on ``topic`` in frame ``map`` (child
    ``base_link``), received when stamped, with t and the position rounded as the CSV rounds
    them (so the bag and the CSV give the same recording); each episode starts with a
    ``std_msgs/msg/Empty`` on ``episode_topic``. The episodes follow each other
    :data:`BAG_EPISODE_PAUSE_S` seconds apart from :data:`BAG_START_S`. Returns the samples written.
    """
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    ros1 = path.suffix == ".bag"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    T = ts.types
    odometry, empty = "nav_msgs/msg/Odometry", "std_msgs/msg/Empty"
    zero3 = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    twist = T["geometry_msgs/msg/TwistWithCovariance"](
        twist=T["geometry_msgs/msg/Twist"](linear=zero3, angular=zero3), covariance=np.zeros(36))
    still = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)

    def message(ns: int, x: float, y: float):
        header = T["std_msgs/msg/Header"](
            **({"seq": 0} if ros1 else {}), frame_id="map",
            stamp=T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000))
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                           orientation=still)
        return T[odometry](header=header, child_frame_id="base_link", twist=twist,
                           pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)))

    n = 0
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.") as tmp:
        inner = Path(tmp) / "bag"
        if ros1:
            writer, made = Writer1(inner), inner
        else:
            plugin = StoragePlugin.MCAP if path.suffix == ".mcap" else StoragePlugin.SQLITE3
            writer, made = Writer2(inner, version=9, storage_plugin=plugin), inner / f"bag{path.suffix}"
        with writer:
            odom = writer.add_connection(topic, odometry, typestore=ts)
            marks = writer.add_connection(episode_topic, empty, typestore=ts)
            start = BAG_START_S * 1_000_000_000
            for _, t, x, y in episodes:
                writer.write(marks, start, serialize(T[empty](), empty))
                ns = start
                for ti, xi, yi in zip(t.tolist(), x.tolist(), y.tolist(), strict=True):
                    ns = start + round(float(f"{ti:.3f}") * 1000) * 1_000_000  # the CSV's milliseconds
                    writer.write(odom, ns, serialize(message(ns, float(f"{xi:.4f}"), float(f"{yi:.4f}")),
                                                     odometry))
                    n += 1
                start = ns + round(BAG_EPISODE_PAUSE_S * 1e9)
        with atomic_path(path) as final:
            os.replace(made, final)
    return n
