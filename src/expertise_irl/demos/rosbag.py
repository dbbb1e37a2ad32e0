"""ROS bags as recordings: the robot's positions on one topic of a ROS 1 ``.bag``, a ROS 2
``.db3`` or ``.mcap`` file, or a ROS 2 bag folder (with ``metadata.yaml``), read with the
pure-Python ``rosbags`` library (no ROS install).

:func:`read_bag` gives the samples a recording CSV holds (episode, t, x, y), by these rules:

- **Positions.** ``nav_msgs/msg/Odometry`` and ``geometry_msgs/msg/PoseWithCovarianceStamped``
  (``pose.pose.position``), ``geometry_msgs/msg/PoseStamped`` (``pose.position``): one sample per
  message. ``tf2_msgs/msg/TFMessage``: one sample per transform whose ``header.frame_id`` is the
  ``parent`` and ``child_frame_id`` the ``child`` (``transform.translation``); only direct
  transforms, no chain through other frames. Frame names are compared without a leading ``/``.
  With ``frame``, a pose message in another frame is an error.
- **Time.** The header stamp (``clock="header"``) or the time the bag received the message
  (``"receive"``), in integer nanoseconds; the samples of an episode are ordered by it (a stable
  sort: a bag stores messages as received) and ``t`` is the seconds since the episode's first one.
- **Episodes.** One per bag; or each message on ``episode_topic`` (``std_msgs/msg/Int32``,
  ``String`` or ``Empty``; its content is ignored) starts a new episode at its receive time:
  the samples received at or after it and before the next one; the samples before the first
  marker are an episode of their own. With ``episode_gap``, two consecutive samples of an
  episode more than that many seconds apart start another. Episodes without samples are
  skipped; the others are numbered 0, 1, 2, ... in time order.

Every problem is an :class:`~expertise_irl.errors.InputError` naming the bag and, where there
is one, the topic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ..errors import InputError, os_reason

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
#: Where each pose type holds its pose (``position`` inside it).
POSE_TYPES = {
    "nav_msgs/msg/Odometry": ("pose", "pose"),
    "geometry_msgs/msg/PoseStamped": ("pose",),
    "geometry_msgs/msg/PoseWithCovarianceStamped": ("pose", "pose"),
}
TF_TYPE = "tf2_msgs/msg/TFMessage"
EPISODE_TYPES = ("std_msgs/msg/Int32", "std_msgs/msg/String", "std_msgs/msg/Empty")
CLOCKS = ("header", "receive")


def is_bag(path: str | Path) -> bool:
    """A ROS bag by its name: a ``.bag``, ``.db3`` or ``.mcap`` file, or a folder."""
    path = Path(path)
    return path.suffix in BAG_SUFFIXES or path.is_dir()


@dataclass(frozen=True)
class BagOptions:
    """How to read a bag (module docstring). ``spelling`` is how messages name the options:
    ``"option"`` (``--topic``, the command line) or ``"column"`` (``bag_topic``, a study manifest)."""

    topic: str | None = None
    child: str | None = None
    parent: str | None = None
    frame: str | None = None
    clock: str = "header"
    episode_topic: str | None = None
    episode_gap: float | None = None
    spelling: str = "option"

    def name(self, option: str) -> str:
        return "--" + option.replace("_", "-") if self.spelling == "option" else "bag_" + option

    def given(self) -> list[str]:
        """The names of the options set to other than their defaults."""
        default = BagOptions()
        return [self.name(f.name) for f in fields(self)
                if f.name != "spelling" and getattr(self, f.name) != getattr(default, f.name)]


@dataclass(frozen=True, eq=False)
class BagSamples:
    """The samples of a bag's topic (arrays ``[N]``, episodes contiguous and in time order).

    ``message`` is the number of each sample's message on the topic, in the bag's order (1 = first).
    """

    topic: str
    episode: np.ndarray
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    message: np.ndarray


def _frame(name: str) -> str:
    return name.lstrip("/")


def _listing(topics: dict) -> str:
    if not topics:
        return "the bag has no topics"
    return "the bag has " + ", ".join(f"{t} ({i.msgtype or 'several types'})" for t, i in topics.items())


def _check_options(path: Path, o: BagOptions) -> None:
    if o.clock not in CLOCKS:
        raise InputError(f"{path}: {o.name('clock')} must be {' or '.join(CLOCKS)}, got {o.clock!r}")
    gap = o.episode_gap
    if gap is not None and not (math.isfinite(gap) and gap > 0):
        raise InputError(f"{path}: {o.name('episode_gap')} must be a number of seconds > 0, got {gap:g}")


def _check_topics(path: Path, o: BagOptions, topics: dict) -> str:
    """The type of the position topic, after checking the topics and the options that go with it."""
    if not o.topic:
        raise InputError(f"{path}: name the topic of the positions ({o.name('topic')}); {_listing(topics)}")
    for opt, want in (("topic", (*POSE_TYPES, TF_TYPE)), ("episode_topic", EPISODE_TYPES)):
        topic = getattr(o, opt)
        if topic is None:
            continue
        if topic not in topics:
            raise InputError(f"{path}: no topic {topic} ({o.name(opt)}); {_listing(topics)}")
        found = topics[topic].msgtype
        if found not in want:
            raise InputError(f"{path}: topic {topic} holds {found or 'several types'}, which "
                             f"{o.name(opt)} does not read (supported: {', '.join(want)})")
    msgtype = topics[o.topic].msgtype
    if msgtype == TF_TYPE:
        if not (o.child and o.parent):
            raise InputError(f"{path}: topic {o.topic} holds {TF_TYPE}: name the transform's frames "
                             f"with {o.name('child')} and {o.name('parent')}")
        if o.frame is not None:
            raise InputError(f"{path}: topic {o.topic}: {o.name('frame')} applies to pose topics; on a tf "
                             f"topic the frame is {o.name('parent')}")
    elif o.child is not None or o.parent is not None:
        raise InputError(f"{path}: topic {o.topic} holds {msgtype}: {o.name('child')} and "
                         f"{o.name('parent')} apply to a {TF_TYPE} topic")
    return msgtype


def _positions(path: Path, o: BagOptions, msgtype: str, msg, number: int) -> list:
    """``[(header, point)]``: the stamped positions one message gives (its ``number`` on the topic)."""
    if msgtype == TF_TYPE:
        return [(tr.header, tr.transform.translation) for tr in msg.transforms
                if _frame(tr.header.frame_id) == _frame(o.parent or "")
                and _frame(tr.child_frame_id) == _frame(o.child or "")]
    if o.frame is not None and _frame(msg.header.frame_id) != _frame(o.frame):
        raise InputError(f"{path}: topic {o.topic}: message {number} is in frame {msg.header.frame_id!r}, "
                         f"expected {o.frame!r} ({o.name('frame')})")
    pose = msg
    for attr in POSE_TYPES[msgtype]:
        pose = getattr(pose, attr)
    return [(msg.header, pose.position)]


def read_bag(path: str | Path, options: BagOptions) -> BagSamples:
    """The samples of ``options.topic`` in the bag at ``path`` (rules in the module docstring).

    Raises
    ------
    InputError
        A missing or unreadable bag, no topic given or no such topic (the message lists the
        bag's topics and types), a topic of an unsupported type, options that do not fit the
        topic, no samples, a message in another frame than ``frame``, a position that is not finite.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag1 import ReaderError as ReaderError1
    from rosbags.rosbag2 import ReaderError as ReaderError2
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    o = options
    _check_options(path, o)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise InputError(f"{path}: is a folder but not a ROS 2 bag (it has no metadata.yaml)")
    header_clock = o.clock == "header"
    t_ns: list[int] = []
    recv_ns: list[int] = []
    xy: list[tuple[float, float]] = []
    number: list[int] = []
    markers: list[int] = []
    pairs: dict[tuple[str, str], None] = {}
    count = 0
    try:
        # a bag without message definitions (an older ROS 2 .db3) is read with ROS 2 Humble's types
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            msgtype = _check_topics(path, o, reader.topics)
            wanted = [c for c in reader.connections if c.topic in (o.topic, o.episode_topic)]
            for conn, received, raw in reader.messages(connections=wanted):
                if conn.topic != o.topic:
                    markers.append(received)
                    continue
                count += 1
                msg = reader.deserialize(raw, conn.msgtype)
                if msgtype == TF_TYPE:  # every (parent, child), for the message when none matches
                    pairs.update(dict.fromkeys((t.header.frame_id, t.child_frame_id) for t in msg.transforms))
                for header, p in _positions(path, o, msgtype, msg, count):
                    x, y = float(p.x), float(p.y)
                    if not (math.isfinite(x) and math.isfinite(y)):
                        raise InputError(f"{path}: topic {o.topic}: message {count}: position "
                                         f"(x={x:g}, y={y:g}) is not finite")
                    stamp = header.stamp
                    t_ns.append(int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec) if header_clock
                                else int(received))
                    recv_ns.append(int(received))
                    xy.append((x, y))
                    number.append(count)
    except (AnyReaderError, ReaderError1, ReaderError2) as exc:
        raise InputError(f"{path}: not a readable ROS bag ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the bag ({os_reason(exc)})") from None
    if not t_ns:
        if msgtype == TF_TYPE and count:
            seen = ", ".join(f"{p or '?'} → {c or '?'}" for p, c in list(pairs)[:10])
            raise InputError(f"{path}: topic {o.topic}: no transform from {o.parent!r} to {o.child!r} "
                             f"in its {count} messages (it holds {seen or 'no transforms'}; only "
                             "direct transforms are read)")
        raise InputError(f"{path}: topic {o.topic} holds no messages")
    return _episodes(o.topic, np.array(t_ns, dtype=np.int64), np.array(recv_ns, dtype=np.int64),
                     np.array(xy), np.array(number, dtype=np.int64), np.array(markers, dtype=np.int64),
                     o.episode_gap)


def _episodes(topic: str, t_ns: np.ndarray, recv_ns: np.ndarray, xy: np.ndarray, number: np.ndarray,
              markers: np.ndarray, gap: float | None) -> BagSamples:
    """Split the samples into episodes and order each by time (module docstring)."""
    piece = np.searchsorted(np.sort(markers), recv_ns, side="right")  # markers at or before each sample
    order = np.lexsort((t_ns, piece))  # stable: by piece, then time, then the bag's order
    t_ns, piece, xy, number = t_ns[order], piece[order], xy[order], number[order]
    new = np.ones(len(t_ns), dtype=bool)
    new[1:] = piece[1:] != piece[:-1]
    if gap is not None:
        new[1:] |= np.diff(t_ns) > round(gap * 1e9)
    episode = np.cumsum(new) - 1
    first = t_ns[np.flatnonzero(new)][episode]
    t = (t_ns - first) / 1e9  # exact nanoseconds before the one rounding to seconds
    return BagSamples(topic, episode.astype(np.int64), t, xy[:, 0].copy(), xy[:, 1].copy(), number)
