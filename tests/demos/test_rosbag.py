"""ROS bags as recordings: real ROS 1 ``.bag`` and ROS 2 ``.db3`` / ``.mcap`` bags, written with
``rosbags``' own writers from a known recording, give exactly the recording CSV's samples and
demonstrations (every supported message type, tf included); episodes split by a topic or a gap;
``--clock receive``; every error with its message; a study manifest with bags; and
``simulate-recordings --out run.mcap``.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from expertise_irl.demos.recordings import discretise, read_recording
from expertise_irl.demos.rosbag import BagOptions
from expertise_irl.errors import InputError
from expertise_irl.userstudy.manifest import read_manifest
from expertise_irl.userstudy.simulated_recordings import RobotMotion, simulate_recordings, write_recording
from expertise_irl.worlds.warehouse import load_floor_plan

PLAN = (
    "S..>>>>>>.\n"
    ".##....#v.\n"
    ".##xx..#v.\n"
    ".......#v.\n"
    "G..<<<<<<G\n"
)
EXAMPLE = Path(__file__).resolve().parents[2] / "src" / "expertise_irl" / "userstudy" / "example"
ODOM, POSE, POSE_COV, TF = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped",
                            "geometry_msgs/msg/PoseWithCovarianceStamped", "tf2_msgs/msg/TFMessage")
START = 1_700_000_000 * 10**9  # the bags' first header stamp
PAUSE = 5 * 10**9  # between two episodes of a bag
STORES = {".bag": get_typestore(Stores.ROS1_NOETIC), "ros2": get_typestore(Stores.ROS2_HUMBLE)}
# rosbags' Noetic store lacks tf2_msgs: its definition in ROS 1 (md5 94810edda583a504dfda3829e70d7eec)
STORES[".bag"].register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A floor plan and a three-episode simulated recording of it (CSV), with its samples."""
    d = tmp_path_factory.mktemp("rosbag")
    (d / "plan.txt").write_text(PLAN, encoding="utf-8")
    (d / "plan.toml").write_text('world = "warehouse"\ncell_size = 0.5\n', encoding="utf-8")
    plan = load_floor_plan(d / "plan.txt")
    recs, _ = simulate_recordings(plan, [0.5, 0.2, 0.3], 0.3, 3, np.random.default_rng(4),
                                  motion=RobotMotion(hz=5))
    write_recording(d / "rec.csv", recs)
    return d, plan, episodes_of(d / "rec.csv")


def episodes_of(path: Path) -> list[tuple[list[int], list[float], list[float]]]:
    """``[(t in ns, x, y)]`` per episode of a recording CSV, as read back (the bag gets these floats)."""
    rec = read_recording(path)
    out = []
    for e in rec.episode_ids.tolist():
        rows = rec.rows_of(e)
        out.append(([round(t * 1000) * 10**6 for t in rec.t[rows].tolist()], rec.x[rows].tolist(),
                    rec.y[rows].tolist()))
    return out


# ------------------------------------------------------------------------------- writing bags
def message(ts, msgtype: str, ns: int, x: float, y: float, frame: str = "map"):
    """A ``msgtype`` message at (x, y), stamped ``ns``; a tf message also holds an unrelated transform."""
    T = ts.types
    ros1 = ts is STORES[".bag"]

    def header(frame_id):
        stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        return T["std_msgs/msg/Header"](**({"seq": 0} if ros1 else {}), stamp=stamp, frame_id=frame_id)

    q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=q)
    with_cov = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36))
    if msgtype == ODOM:
        v = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=v, angular=v), covariance=np.zeros(36))
        return T[ODOM](header=header(frame), child_frame_id="base_link", pose=with_cov, twist=twist)
    if msgtype == POSE:
        return T[POSE](header=header(frame), pose=pose)
    if msgtype == POSE_COV:
        return T[POSE_COV](header=header(frame), pose=with_cov)

    def transform(parent, child, tx, ty):
        tr = T["geometry_msgs/msg/Transform"](translation=T["geometry_msgs/msg/Vector3"](x=tx, y=ty, z=0.0),
                                              rotation=q)
        return T["geometry_msgs/msg/TransformStamped"](header=header(parent), child_frame_id=child,
                                                       transform=tr)

    return T[TF](transforms=[transform("odom", "base_link", -9.0, -9.0), transform(frame, "base_link", x, y)])


def std_msg(ts, msgtype: str, k: int):
    return {"std_msgs/msg/Int32": lambda: ts.types[msgtype](data=k),
            "std_msgs/msg/String": lambda: ts.types[msgtype](data=f"episode {k}"),
            "std_msgs/msg/Empty": lambda: ts.types[msgtype]()}[msgtype]()


def write_bag(path: Path, episodes, msgtype: str = ODOM, *, topic: str = "/odom", frame: str = "map",
              marker: str | None = "std_msgs/msg/Empty", latency: int = 0, stamp=None,
              markers: list[int] | None = None, extra: dict[str, str] | None = None) -> Path:
    """A bag of ``episodes`` (``[(t ns, x, y)]``, t from 0), by the suffix: ``.bag`` (ROS 1), or a ROS 2
    bag folder named ``path`` whose storage is ``.db3`` / ``.mcap`` (``path`` without that suffix).

    Episodes follow each other PAUSE apart from START; each starts with a ``marker`` on /episode
    (None: no /episode topic; ``markers``: at these receive times instead). Messages are received
    ``latency`` ns after their stamp; ``stamp(ns)`` overrides the stamp. ``extra``: other topics,
    left empty."""
    ros1 = path.suffix == ".bag"
    ts = STORES[".bag" if ros1 else "ros2"]
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    if ros1:
        writer = Writer1(path)
    else:
        plugin = StoragePlugin.MCAP if path.suffix == ".mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path.with_suffix(""), version=9, storage_plugin=plugin)
    with writer:
        conn = writer.add_connection(topic, msgtype, typestore=ts)
        mark = writer.add_connection("/episode", marker, typestore=ts) if marker else None
        for name, typ in (extra or {}).items():
            writer.add_connection(name, typ, typestore=ts)
        start, queue = START, []
        for k, (t, x, y) in enumerate(episodes):
            if mark is not None and markers is None:
                queue.append((start + latency - 1, mark, serialize(std_msg(ts, marker, k), marker)))
            for ti, xi, yi in zip(t, x, y, strict=True):
                ns = start + ti
                msg = message(ts, msgtype, stamp(ns) if stamp else ns, xi, yi, frame)
                queue.append((ns + latency, conn, serialize(msg, msgtype)))
            start += t[-1] + PAUSE
        for k, at in enumerate(markers or []):
            queue.append((at, mark, serialize(std_msg(ts, marker, k), marker)))
        for at, c, raw in sorted(queue, key=lambda q: q[0]):
            writer.write(c, at, raw)
    return path if ros1 else path.with_suffix("")


def same(a, b) -> None:
    """Two discretisations are the same demonstrations."""
    for f in ("episode", "step", "state", "action"):
        assert getattr(a.trajectories, f).tolist() == getattr(b.trajectories, f).tolist(), f
    assert [e.kept.tolist() for e in a.episodes] == [e.kept.tolist() for e in b.episodes]


# ----------------------------------------------------------------------- the same recording
@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".bag", ".db3", ".mcap"])
@pytest.mark.parametrize("msgtype", [ODOM, POSE, POSE_COV, TF])
def test_every_format_and_message_type_gives_the_csv_samples_and_demonstrations(study, tmp_path, suffix,
                                                                                   msgtype):
    d, plan, eps = study
    topic = "/tf" if msgtype == TF else "/pose"
    bag = write_bag(tmp_path / f"run{suffix}", eps, msgtype, topic=topic, latency=3_000_000)
    tf = {"child": "base_link", "parent": "map"} if msgtype == TF else {"frame": "map"}
    opts = BagOptions(topic=topic, episode_topic="/episode", **tf)
    rec, want = read_recording(bag, opts), read_recording(d / "rec.csv")
    for f in ("episode", "t", "x", "y"):
        assert getattr(rec, f).tolist() == getattr(want, f).tolist(), f
    assert rec.source == f"{bag}:{topic}"
    assert rec.line.tolist() == list(range(1, len(rec.t) + 1))
    same(discretise(rec, plan), discretise(want, plan))
    if suffix != ".bag":  # the storage file alone, without its folder, is a bag too
        alone = read_recording(bag / f"{bag.name}{suffix}", opts)
        assert alone.t.tolist() == want.t.tolist() and alone.x.tolist() == want.x.tolist()


def test_discretise_reads_a_ros1_bag_of_the_bundled_example_as_it_reads_the_csv(tmp_path):
    eps = episodes_of(EXAMPLE / "recordings" / "P01.csv")
    bag = write_bag(tmp_path / "P01.bag", eps, marker=None)
    plan = EXAMPLE / "spec-a.txt"
    ok(res := invoke("discretise", plan, "--recording", bag, "--topic", "/odom", "--frame", "map",
                     "--out", tmp_path / "bag.csv"))
    assert "episode 0: 934 samples, 95 kept at 1 Hz, 70 moves, reached a goal" in res.output
    ok(invoke("discretise", plan, "--recording", EXAMPLE / "recordings" / "P01.csv",
              "--out", tmp_path / "csv.csv"))
    assert (tmp_path / "bag.csv").read_bytes() == (tmp_path / "csv.csv").read_bytes()
    assert (tmp_path / "bag.png").is_file()


@pytest.mark.slow
def test_simulate_recordings_writes_a_bag_of_the_csvs_samples(study, tmp_path):
    d = study[0]
    sim = ("simulate-recordings", d / "plan.txt", "--theta", "0.5,0.2,0.3", "--beta", "0.3",
           "--episodes", "2", "--seed", "3", "--hz", "4")
    outs = {}
    for name in ("run.csv", "run.mcap", "run.db3", "run.bag"):
        ok(res := invoke(*sim, "--out", tmp_path / name))
        assert f"wrote {tmp_path / name}: 2 episodes" in res.output
        bag = () if name.endswith(".csv") else ("--topic", "/odom", "--frame", "map",
                                                "--episode-topic", "/episode")
        ok(invoke("discretise", d / "plan.txt", "--recording", tmp_path / name, *bag,
                  "--out", tmp_path / f"{name}.demos.csv"))
        outs[name] = (tmp_path / f"{name}.demos.csv").read_bytes()
    assert len(set(outs.values())) == 1
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left over
    # one episode per bag without --episode-topic: the second is driving on after the first's goal
    ok(res := invoke("discretise", d / "plan.txt", "--recording", tmp_path / "run.mcap", "--topic", "/odom",
                     "--out", tmp_path / "x.csv"))
    assert "1 episode," in res.output and "the robot drove on after entering a goal" in res.output


# ---------------------------------------------------------------------------------- episodes
def test_a_gap_longer_than_episode_gap_starts_an_episode(study, tmp_path):
    d, plan, eps = study
    bag = write_bag(tmp_path / "run.mcap", eps, marker=None)
    rec = read_recording(bag, BagOptions(topic="/odom", episode_gap=3.0))
    want = read_recording(d / "rec.csv")
    assert rec.episode.tolist() == want.episode.tolist() and rec.t.tolist() == want.t.tolist()
    same(discretise(rec, plan), discretise(want, plan))
    assert len(set(read_recording(bag, BagOptions(topic="/odom", episode_gap=6.0)).episode.tolist())) == 1


@pytest.mark.parametrize("marker", ["std_msgs/msg/Int32", "std_msgs/msg/String", "std_msgs/msg/Empty"])
def test_each_message_on_the_episode_topic_starts_an_episode_at_its_receive_time(tmp_path, marker):
    t = [k * 10**9 for k in range(8)]
    xs = [0.25 + 0.5 * k for k in range(8)]
    # markers: before every sample, at the third sample's time (it starts the new episode), twice
    # between the fifth and sixth (an episode without samples is skipped)
    at = [START - 10, START + 2 * 10**9, START + 4 * 10**9 + 1, START + 4 * 10**9 + 2]
    bag = write_bag(tmp_path / "run.db3", [(t, xs, [0.25] * 8)], marker=marker, markers=at)
    rec = read_recording(bag, BagOptions(topic="/odom", episode_topic="/episode"))
    assert rec.episode.tolist() == [0, 0, 1, 1, 1, 2, 2, 2]
    assert rec.t.tolist() == [0, 1, 0, 1, 2, 0, 1, 2]  # seconds since the episode's first sample
    assert rec.x.tolist() == xs
    # samples before the first marker are an episode of their own
    rec = read_recording(bag, BagOptions(topic="/odom", episode_topic="/episode", episode_gap=0.5))
    assert rec.episode.tolist() == list(range(8))
    late = write_bag(tmp_path / "late.bag", [(t, xs, [0.25] * 8)], marker=marker, markers=[START + 3 * 10**9])
    assert read_recording(late, BagOptions(topic="/odom", episode_topic="/episode")).episode.tolist() == \
        [0, 0, 0, 1, 1, 1, 1, 1]


# ------------------------------------------------------------------------------------- clock
def test_clock_receive_uses_the_bags_receive_time_and_header_orders_by_the_stamps(study, tmp_path):
    d, _, eps = study
    # stamps that run backwards within each episode (a wrong clock); the bag received them in order
    (t, x, y), = eps[:1]
    bag = write_bag(tmp_path / "run.bag", [(t, x, y)], latency=250_000_000,
                    stamp=lambda ns: START + 10**12 - (ns - START))
    want = read_recording(d / "rec.csv")
    rows = want.rows_of(0)
    rec = read_recording(bag, BagOptions(topic="/odom", clock="receive"))
    assert rec.t.tolist() == want.t[rows].tolist() and rec.x.tolist() == want.x[rows].tolist()
    by_stamp = read_recording(bag, BagOptions(topic="/odom"))
    assert by_stamp.x.tolist() == want.x[rows].tolist()[::-1]  # ordered by the header stamps
    assert by_stamp.line.tolist() == list(range(len(rows), 0, -1))  # each keeps its message number


# ------------------------------------------------------------------------------------ errors
@pytest.fixture
def bag(study, tmp_path):
    """A ROS 2 mcap bag: /odom in frame odom, /tf, /episode, and an empty /pose."""
    eps = study[2][:1]
    b = write_bag(tmp_path / "run.mcap", eps, frame="odom", extra={"/pose": POSE, "/tf": TF})
    return b


def error(path, **options) -> str:
    with pytest.raises(InputError) as exc:
        read_recording(path, BagOptions(**options))
    assert "\n" not in str(exc.value)
    return str(exc.value)


def test_every_bag_error_is_one_line_naming_the_file_and_topic(bag, tmp_path):
    listing = ("the bag has /episode (std_msgs/msg/Empty), /odom (nav_msgs/msg/Odometry), "
               "/pose (geometry_msgs/msg/PoseStamped), /tf (tf2_msgs/msg/TFMessage)")
    assert error(bag) == f"{bag}: name the topic of the positions (--topic); {listing}"
    assert error(bag, topic="/nope") == f"{bag}: no topic /nope (--topic); {listing}"
    assert error(bag, topic="/episode") == (
        f"{bag}: topic /episode holds std_msgs/msg/Empty, which --topic does not read (supported: "
        f"{ODOM}, {POSE}, {POSE_COV}, {TF})")
    assert error(bag, topic="/odom", episode_topic="/odom") == (
        f"{bag}: topic /odom holds {ODOM}, which --episode-topic does not read (supported: "
        "std_msgs/msg/Int32, std_msgs/msg/String, std_msgs/msg/Empty)")
    assert error(bag, topic="/odom", episode_topic="/nope").startswith(
        f"{bag}: no topic /nope (--episode-topic)")
    assert error(bag, topic="/pose") == f"{bag}: topic /pose holds no messages"
    assert error(bag, topic="/tf", child="base_link", parent="map") == f"{bag}: topic /tf holds no messages"
    assert error(bag, topic="/tf", child="base_link") == (
        f"{bag}: topic /tf holds {TF}: name the transform's frames with --child and --parent")
    assert "--frame applies to pose topics" in error(bag, topic="/tf", child="a", parent="b", frame="map")
    assert error(bag, topic="/odom", child="base_link") == (
        f"{bag}: topic /odom holds {ODOM}: --child and --parent apply to a {TF} topic")
    assert error(bag, topic="/odom", frame="map") == (
        f"{bag}: topic /odom: message 1 is in frame 'odom', expected 'map' (--frame)")
    assert error(bag, topic="/odom", frame="/odom", clock="wall") == (
        f"{bag}: --clock must be header or receive, got 'wall'")
    assert error(bag, topic="/odom", episode_gap=0.0) == (
        f"{bag}: --episode-gap must be a number of seconds > 0, got 0")
    read_recording(bag, BagOptions(topic="/odom", frame="/odom"))  # frames compare without a leading /


def test_a_tf_topic_without_the_transform_lists_the_ones_it_holds(study, tmp_path):
    b = write_bag(tmp_path / "tf.bag", study[2][:1], TF, topic="/tf", marker=None)
    n = len(study[2][0][0])
    assert error(b, topic="/tf", child="base_link", parent="world") == (
        f"{b}: topic /tf: no transform from 'world' to 'base_link' in its {n} messages (it holds odom → "
        "base_link, map → base_link; only direct transforms are read)")


def test_unreadable_bags_and_bag_options_on_a_csv_are_errors(study, tmp_path):
    for name, content in (("bad.bag", b"not a bag"), ("bad.mcap", b""), ("bad.db3", b"SQLite? no")):
        (tmp_path / name).write_bytes(content)
        assert error(tmp_path / name, topic="/odom").startswith(
            f"{tmp_path / name}: not a readable ROS bag (")
    assert error(tmp_path / "none.mcap", topic="/odom") == f"{tmp_path / 'none.mcap'}: no such file"
    (tmp_path / "folder").mkdir()
    assert error(tmp_path / "folder", topic="/odom") == (
        f"{tmp_path / 'folder'}: is a folder but not a ROS 2 bag (it has no metadata.yaml)")
    csv_path = study[0] / "rec.csv"
    assert error(csv_path, topic="/odom", clock="receive") == (
        f"{csv_path}: --topic, --clock apply to a ROS bag (.bag, .db3, .mcap or a ROS 2 bag folder), "
        "not to a CSV recording")


def test_the_cli_turns_bag_errors_into_one_line_and_exit_2(study, bag, tmp_path):
    plan = study[0] / "plan.txt"
    run = ("discretise", plan, "--recording", bag, "--out", tmp_path / "d.csv")
    assert_input_error(invoke(*run, "--topic", "/nope"), f"{bag}: no topic /nope (--topic)",
                       "/odom (nav_msgs")
    assert_input_error(invoke(*run, "--topic", "/odom", "--frame", "map"),
                       f"{bag}: topic /odom: message 1 is in frame 'odom', expected 'map' (--frame)")
    assert_input_error(invoke(*run, "--topic", "/odom", "--clock", "wall"),
                       "--clock must be header or receive")
    (tmp_path / "bad.bag").write_bytes(b"#ROSBAG V2.0\nbroken")
    assert_input_error(invoke("discretise", plan, "--recording", tmp_path / "bad.bag", "--topic", "/odom",
                              "--out", tmp_path / "d.csv"), "bad.bag: not a readable ROS bag")
    # the ingestion rules name the bag, the topic and the message
    far = write_bag(tmp_path / "far.bag", [([0, 10**9, 2 * 10**9], [0.25, 0.75, 9.0], [0.25] * 3)],
                    marker=None)
    assert_input_error(invoke("discretise", plan, "--recording", far, "--topic", "/odom", "--out",
                              tmp_path / "d.csv"),
                       f"{far}:/odom:3: episode 0 t=2: sample (x=9, y=0.25) is outside the map")


# ---------------------------------------------------------------------------------- manifest
def manifest_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_a_study_manifest_takes_bags_with_their_options_in_bag_columns(study, tmp_path):
    d, _, eps = study
    for name in ("plan.txt", "plan.toml", "rec.csv"):
        (tmp_path / name).write_bytes((d / name).read_bytes())
    write_bag(tmp_path / "p1.mcap", eps)
    write_bag(tmp_path / "p2.bag", eps, TF, topic="/tf", marker=None)
    (tmp_path / "manifest.csv").write_text(
        "participant,map,recording,condition,bag_topic,bag_child,bag_parent,bag_clock,bag_episode_topic,"
        "bag_episode_gap\n"
        "P1,plan.txt,p1,do,/odom,,,receive,/episode,\n"
        "P2,plan.txt,p2.bag,show,/tf,base_link,map,,,3\n"
        "P3,plan.txt,rec.csv,do,,,,,,\n", encoding="utf-8")
    m = read_manifest(tmp_path / "manifest.csv")
    assert m.extra_columns == ("condition",)
    assert [t.extra for t in m.tasks] == [{"condition": "do"}, {"condition": "show"}, {"condition": "do"}]
    for t in m.tasks:
        same(t.discretised, m.tasks[2].discretised)

    out = tmp_path / "out"
    ok(invoke("study", tmp_path / "manifest.csv", "--out", out, "--workers", "1", "--figures", "none"))
    rows = manifest_rows(out / "study.csv")
    assert [r["participant"] for r in rows] == ["P1", "P2", "P3"] and [r["condition"] for r in rows] == \
        ["do", "show", "do"]
    assert not any(c.startswith("bag_") for c in rows[0])
    assert len({r["beta_hat"] for r in rows}) == 1  # the same demonstrations
    ok(invoke("study", tmp_path / "manifest.csv", "--out", out, "--workers", "1", "--figures", "none"))

    def bad(row: str, *fragments: str) -> None:
        (tmp_path / "manifest.csv").write_text(
            "participant,map,recording,bag_topic,bag_episode_gap\n" + row + "\n", encoding="utf-8")
        assert_input_error(invoke("study", tmp_path / "manifest.csv", "--out", tmp_path / "o"),
                           f"{tmp_path / 'manifest.csv'}:2: ", *fragments)

    bad("P1,plan.txt,p1,,", f"{tmp_path / 'p1'}: name the topic of the positions (bag_topic); the bag has")
    bad("P1,plan.txt,p1,/odom,x", "bag_episode_gap 'x' is not a number of seconds")
    bad("P1,plan.txt,p1,/odom,-1", "bag_episode_gap must be a number of seconds > 0, got -1")
    bad("P1,plan.txt,rec.csv,/odom,", "bag_topic apply to a recording that is a ROS bag",
        "not to a CSV recording")
    bad("P1,plan.txt,p2.bag,/odom,",
        "p2.bag: no topic /odom (bag_topic); the bag has /tf (tf2_msgs/msg/TFMessage)")
