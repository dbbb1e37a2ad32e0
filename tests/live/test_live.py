"""The live server in-process: WebSocket protocol (good and bad messages), recording and resume,
static files confined to the package, origin and host checks; the ``live`` and ``next-start``
commands."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke, ok
from goal_paths import path_to_goal
from starlette.testclient import TestClient

from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, theta_grid
from expertise_irl.inference.belief import DiscreteBelief
from expertise_irl.live.server import LOOPBACK_NAMES, MAX_MESSAGE, create_app
from expertise_irl.live.session import open_session
from expertise_irl.mdp import ACTION_NAMES
from expertise_irl.worlds.zones import parse_map

MAP = """\
.....
.xx..
...>G
"""
BASE = "http://127.0.0.1:8765"
WS = "ws://127.0.0.1:8765/ws"


@pytest.fixture(scope="module")
def zone_map():
    return parse_map(MAP, name="small")


@pytest.fixture(scope="module")
def hyp():
    return HypothesisSet(theta_grid((0.0, 1.0), 5), BETA_PRESETS["paper-sim"])


def make(zone_map, hyp, out, **kw):
    session = open_session(zone_map, hyp, out, settings={"command": "live", "mdp_digest": "sha256:x"}, **kw)
    client = TestClient(create_app(session, allowed_hosts=list(LOOPBACK_NAMES)), base_url=BASE)
    return session, client


def move(ws, action: str) -> dict:
    ws.send_text(json.dumps({"type": "move", "action": action}))
    return ws.receive_json()


def test_protocol_moves_update_the_estimate_and_the_recording(tmp_path, zone_map, hyp):
    session, client = make(zone_map, hyp, tmp_path)
    mdp = session.mdp
    with client.websocket_connect(WS) as ws:
        init = ws.receive_json()
        assert init["type"] == "init"
        assert init["map"]["rows"] == MAP.splitlines()
        assert init["feature_names"] == list(mdp.feature_names)
        assert init["colors"]["goal"] and init["colors"]["zones"]["x"]
        state = init["state"]
        assert state["actions"] == 0 and state["start"]["how"] == "active"
        assert "expected to reduce the uncertainty" in state["start"]["why"]
        s = int(session.position)
        prior = DiscreteBelief.from_log_policy(hyp, session.estimator.belief().log_policy)
        pairs = []
        for a in path_to_goal(mdp, s)[:-1]:  # stop one move short of the goal
            r = move(ws, ACTION_NAMES[a])
            pairs.append((s, a))
            s = int(mdp.next_state[s, a])
            assert r["type"] == "state" and r["event"] == "moved"
            assert r["position"] == mdp.state_xy[s].tolist()
            assert r["actions"] == len(pairs) and len(r["history"]["beta_hat"]) == len(pairs)
            ref = prior.update_pairs(*zip(*pairs, strict=True))
            assert r["estimate"]["beta_hat"] == pytest.approx(ref.mean_beta, abs=1e-12)
            assert r["estimate"]["entropy"] == pytest.approx(ref.entropy, abs=1e-12)
            assert len(r["estimate"]["beta_probabilities"]) == hyp.n_beta
            assert r["path"][-1] == r["position"] and len(r["path"]) == len(pairs) + 1
    trajs = read_demos_csv(tmp_path / "demos.csv", mdp)  # on disk, in the project's format
    assert list(zip(trajs.state.tolist(), trajs.action.tolist(), strict=True)) == pairs
    doc = json.loads((tmp_path / "result.json").read_text())  # written at the start and per episode
    assert doc["data"]["actions"] == 0 and doc["settings"]["mdp_digest"] == "sha256:x"


def test_a_move_that_cannot_be_written_is_not_counted(tmp_path, zone_map, hyp):
    session, client = make(zone_map, hyp, tmp_path)
    (tmp_path / "demos.csv").mkdir()  # appending to it fails
    s = session.position
    a = next(a for a in range(4) if session.mdp.next_state[s, a] >= 0)
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        r = move(ws, ACTION_NAMES[a])
        assert r["type"] == "error" and "not counted" in r["message"]
    assert session.estimator.n_observed == 0 and session.position == s
    assert not session.estimator.episode_open


def test_wall_is_refused_and_not_recorded(tmp_path, zone_map, hyp):
    session, client = make(zone_map, hyp, tmp_path)
    mdp = session.mdp
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        s = session.position
        blocked = [a for a in range(4) if mdp.next_state[s, a] < 0]
        assert blocked, "the start should be on the edge of this small map"
        r = move(ws, ACTION_NAMES[blocked[0]])
        assert r["type"] == "refused" and "not recorded" in r["message"]
        assert session.estimator.n_observed == 0 and session.position == s
        assert not (tmp_path / "demos.csv").exists()


@pytest.mark.parametrize("raw, fragment", [
    ("{not json", "not valid JSON"),
    ("[1, 2]", "JSON object"),
    ('{"type": "teleport"}', "unknown message type"),
    ('{"action": "up"}', "unknown message type"),
    ('{"type": "move", "action": "jump"}', "unknown action"),
    ('{"type": "move", "action": 3}', "unknown action"),
    ('{"type": "move"}', "needs the field"),
    ('{"type": "move", "action": "up", "path": "../../etc/passwd"}', "unexpected field"),
    ('{"type": "mode", "mode": "greedy"}', "unknown mode"),
    ('{"type": "sync", "file": "result.json"}', "unexpected field"),
    ('{"type": "move", "action": "' + "u" * MAX_MESSAGE + '"}', "too large"),
])
def test_bad_messages_get_an_error_and_the_connection_survives(tmp_path, zone_map, hyp, raw, fragment):
    session, client = make(zone_map, hyp, tmp_path)
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        ws.send_text(raw)
        r = ws.receive_json()
        assert r["type"] == "error" and fragment in r["message"], r
        ws.send_bytes(b"\x00\x01")
        assert ws.receive_json()["type"] == "error"
        ws.send_text('{"type": "sync"}')
        assert ws.receive_json()["type"] == "state"  # still served
    assert session.estimator.n_observed == 0


def test_episode_end_writes_result_and_picks_the_next_start(tmp_path, zone_map, hyp):
    session, client = make(zone_map, hyp, tmp_path)
    mdp = session.mdp
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        for episode, mode in enumerate(("active", "random")):
            ws.send_text(json.dumps({"type": "mode", "mode": mode}))
            assert ws.receive_json()["mode"] == mode
            for a in path_to_goal(mdp, session.position):
                r = move(ws, ACTION_NAMES[a])
            assert r["event"] == "episode_done" and "Goal reached" in r["message"]
            assert f"(episode {episode} done;" in r["message"]  # numbered as in demos.csv
            assert r["episodes_done"] == episode + 1 and r["step"] == 0 and r["episode"] == episode + 1
            assert r["start"]["how"] == mode and r["path"] == [r["position"]]
            doc = json.loads((tmp_path / "result.json").read_text())
            assert doc["data"]["episodes"] == episode + 1 and doc["data"]["actions"] == r["actions"]
            assert doc["beta_hat"] == pytest.approx(r["estimate"]["beta_hat"])
            # The toggle decides the *next* start; both recorded starts were chosen while active.
            assert [d["how"] for d in doc["live"]["starts"]] == ["active"] * (episode + 1)
        assert "drawn uniformly" in r["start"]["why"]
    trajs = read_demos_csv(tmp_path / "demos.csv", mdp)
    assert trajs.n_episodes == 2 and len(trajs) == session.estimator.n_observed
    rows = (tmp_path / "demos.csv").read_text().splitlines()[1:]
    assert sorted({int(r.split(",")[0]) for r in rows}) == [0, 1]  # the page's episode numbers


def test_the_start_mode_survives_a_restart(tmp_path, zone_map, hyp):
    """The random/active toggle is kept in result.json: a restart before any move, between
    episodes and mid-episode comes back in the mode the page last set."""
    def starts():
        return [(d["episode"], d["how"]) for d in json.loads((tmp_path / "result.json").read_text())[
            "live"]["starts"]]

    session, client = make(zone_map, hyp, tmp_path)
    mdp = session.mdp
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        ws.send_text(json.dumps({"type": "mode", "mode": "random"}))
        assert ws.receive_json()["mode"] == "random"
    assert json.loads((tmp_path / "result.json").read_text())["live"]["mode"] == "random"
    again, client = make(zone_map, hyp, tmp_path)  # stopped before the first move
    assert again.mode == "random" and again.start.how == "random"
    with client.websocket_connect(WS) as ws:
        assert ws.receive_json()["state"]["mode"] == "random"
        for a in path_to_goal(mdp, again.position):
            r = move(ws, ACTION_NAMES[a])
        assert r["event"] == "episode_done" and r["start"]["how"] == "random"
    third, client = make(zone_map, hyp, tmp_path)  # stopped between episodes: the same start again
    assert third.mode == "random" and third.position == again.position
    assert starts() == [(0, "random"), (1, "random")]  # one entry per episode, not one per restart
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        move(ws, ACTION_NAMES[path_to_goal(mdp, third.position)[0]])
    fourth, client = make(zone_map, hyp, tmp_path)  # stopped mid-episode 1
    assert fourth.mode == "random" and fourth.start.how == "resumed"
    with client.websocket_connect(WS) as ws:
        state = ws.receive_json()["state"]
        assert state["mode"] == "random" and state["episode"] == 1
        assert state["start"]["why"].startswith("Resumed episode 1 ")
        ws.send_text(json.dumps({"type": "mode", "mode": "active"}))
        assert ws.receive_json()["mode"] == "active"
    assert make(zone_map, hyp, tmp_path)[0].mode == "active"


def test_killed_mid_episode_resumes_from_disk(tmp_path, zone_map, hyp):
    session, client = make(zone_map, hyp, tmp_path)
    mdp = session.mdp
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        for a in path_to_goal(mdp, session.position):
            move(ws, ACTION_NAMES[a])
        s = session.position
        todo = path_to_goal(mdp, s)
        assert len(todo) >= 2
        move(ws, ACTION_NAMES[todo[0]])  # episode 2 is cut off after one move
    expected = session.estimator.estimate
    del session, client  # the server is gone; only the files remain
    again, client = make(zone_map, hyp, tmp_path)
    est = again.estimator
    assert est.n_observed == expected.n_observed and est.episode_open
    assert est.estimate.beta_hat == pytest.approx(expected.beta_hat, abs=1e-12)
    assert again.position == int(mdp.next_state[s, todo[0]])
    assert again.start.how == "resumed"
    assert len(again.history_beta) == est.n_observed
    with client.websocket_connect(WS) as ws:
        state = ws.receive_json()["state"]
        assert state["episode"] == 1 and state["step"] == 1 and len(state["path"]) == 2
        for a in todo[1:]:
            r = move(ws, ACTION_NAMES[a])
        assert r["event"] == "episode_done"
    trajs = read_demos_csv(tmp_path / "demos.csv", mdp)
    assert trajs.n_episodes == 2 and trajs.episodes()[1][1].tolist() == todo


def test_resume_refuses_a_directory_of_another_map(tmp_path, zone_map, hyp):
    from expertise_irl.errors import InputError

    make(zone_map, hyp, tmp_path / "a")  # no action yet: result.json already names the map
    other = dict(settings={"command": "live", "mdp_digest": "sha256:other"})
    with pytest.raises(InputError, match="recorded on another map"):
        open_session(zone_map, hyp, tmp_path / "a", **other)


def test_static_files_only_from_the_package(tmp_path, zone_map, hyp):
    _, client = make(zone_map, hyp, tmp_path)
    r = client.get("/")
    assert r.status_code == 200 and "<canvas id=\"map\"" in r.text
    assert "default-src 'self'" in r.headers["content-security-policy"]
    assert "http" not in r.text.replace("http-equiv", "")  # no CDN, nothing from the network
    for name in ("live.js", "live.css"):
        assert client.get(f"/static/{name}").status_code == 200
    for path in ("/static/../session.py", "/static/..%2fsession.py", "/static/%2e%2e/%2e%2e/cli/core.py",
                 "/static/..%2f..%2f..%2f..%2fpyproject.toml", "/static//etc/passwd", "/../server.py",
                 "/static/%2e%2e%5cserver.py", "/demos.csv", "/result.json"):
        r = client.get(path)
        assert r.status_code == 404, path
        assert "import" not in r.text and "root:" not in r.text


def test_other_origins_and_hosts_are_refused(tmp_path, zone_map, hyp):
    from starlette.websockets import WebSocketDisconnect

    _, client = make(zone_map, hyp, tmp_path)
    with pytest.raises(WebSocketDisconnect):
        with client.websocket_connect(WS, headers={"origin": "http://evil.example"}) as ws:
            ws.receive_json()
    with client.websocket_connect(WS, headers={"origin": BASE}) as ws:
        assert ws.receive_json()["type"] == "init"
    assert client.get("/", headers={"host": "evil.example"}).status_code == 400


# ------------------------------------------------------------------------- commands
def spawn_live(map_path, out):
    """Start ``expertise-irl live`` on a free loopback port; (process, ws URL)."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    exe = Path(sys.executable).with_name("expertise-irl")
    proc = subprocess.Popen([str(exe), "live", str(map_path), "--thetas", "0,1", "--out", str(out),
                             "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()  # the solve comes first; the URL is the first line on stdout
    m = re.search(r"http://(127\.0\.0\.1:\d+)/", line)
    assert m, f"no URL in {line!r}: {proc.stderr.read() if proc.poll() is not None else ''}"
    return proc, f"ws://{m.group(1)}/ws"


@pytest.mark.slow
def test_sigkill_mid_episode_then_restart_resumes(tmp_path, zone_map):
    """The real server, killed with SIGKILL mid-episode: what was done is on disk and resumes."""
    import asyncio
    import signal

    import websockets

    map_path = tmp_path / "small.txt"
    map_path.write_text(MAP)
    out = tmp_path / "rec"
    mdp = zone_map.to_mdp()

    async def drive(url, n, mode=None):
        async with websockets.connect(url) as ws:
            state = json.loads(await ws.recv())["state"]
            await ws.send("x" * 50_000)  # oversized for the protocol, answered, not fatal
            assert "too large" in json.loads(await ws.recv())["message"]
            if mode is not None:
                await ws.send(json.dumps({"type": "mode", "mode": mode}))
                assert json.loads(await ws.recv())["mode"] == mode
            s = int(zone_map.state_index()[state["position"][1], state["position"][0]])
            plan = path_to_goal(mdp, s)
            for a in plan[:n]:
                await ws.send(json.dumps({"type": "move", "action": ACTION_NAMES[a]}))
                state = json.loads(await ws.recv())
            return state, plan

    proc, url = spawn_live(map_path, out)
    try:
        before, plan = asyncio.run(drive(url, 2, mode="random"))
        assert before["actions"] == 2 and len(plan) > 2
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    on_disk = read_demos_csv(out / "demos.csv", mdp)
    assert on_disk.action.tolist() == plan[:2]
    proc, url = spawn_live(map_path, out)
    try:
        after, rest = asyncio.run(drive(url, 0))
        assert after["actions"] == 2 and after["step"] == 2 and after["position"] == before["position"]
        assert after["estimate"]["beta_hat"] == pytest.approx(before["estimate"]["beta_hat"], abs=1e-12)
        assert after["start"]["how"] == "resumed" and rest == plan[2:]
        assert after["mode"] == "random"  # the page's toggle, as it was left
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)



def test_live_command_prints_its_url_and_warns_off_loopback(tmp_path, monkeypatch):
    import expertise_irl.live.server as server

    served = []
    monkeypatch.setattr(server, "serve", lambda session, sock, on_ready: (
        served.append(sock.getsockname()), on_ready(server.url_of(sock)), sock.close()))
    r = invoke("live", "corridor", "--thetas", "0,1", "--out", tmp_path / "rec", "--port", 0)
    ok(r)
    host, port = served[0][:2]
    assert host == "127.0.0.1" and f"live page: http://127.0.0.1:{port}/" in r.stdout
    assert "warning" not in r.stderr
    r = invoke("live", "corridor", "--thetas", "0,1", "--out", tmp_path / "rec", "--port", 0,
               "--host", "0.0.0.0")
    ok(r)
    assert "reachable from other machines" in r.stderr


def test_live_command_bad_input(tmp_path):
    (tmp_path / "file").write_text("x")
    assert_input_error(invoke("live", "corridor", "--out", tmp_path / "file", "--port", 0), "not a directory")
    assert_input_error(invoke("live", "nosuchmap", "--port", 0), "nosuchmap")
    assert_input_error(invoke("live", "corridor", "--betas", "0,1", "--port", 0), "--betas")
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        assert_input_error(invoke("live", "corridor", "--out", tmp_path / "r0", "--port", port),
                           f"--port {port}", "cannot listen")
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "demos.csv").write_text("episode,step,x,y\n0,0,0,0\n0,1,3,0\n")  # a jump: not resumable
    assert_input_error(invoke("live", "corridor", "--out", rec, "--port", 0), "demos.csv", "jumps")


def test_live_command_without_a_set_is_adaptive(tmp_path, monkeypatch):
    """No set named: the start set, refined after each episode; --no-refine and --expertise changing
    keep the fixed paper-real × paper-sim set; --refine cannot follow a changing β."""
    import expertise_irl.live.server as server
    from expertise_irl.inference.adaptive import start_set

    monkeypatch.setattr(server, "serve", lambda session, sock, on_ready: (
        on_ready(server.url_of(sock)), sock.close()))

    def settings(*args):
        out = tmp_path / str(len(list(tmp_path.iterdir())))
        r = invoke("live", "corridor", *args, "--out", out, "--port", 0)
        ok(r)
        return r.stdout, json.loads((out / "result.json").read_text())["settings"]

    stdout, s = settings()
    assert "refined after each episode" in stdout
    assert s["hypotheses"] == s["thetas"] == s["betas"] == "adaptive"
    assert s["n_hypotheses"] == len(start_set(5))  # the five zone-map features
    for args in (("--no-refine",), ("--expertise", "changing")):
        stdout, s = settings(*args)
        assert "refined" not in stdout, args
        assert (s["hypotheses"], s["thetas"], s["betas"]) == ("fixed", "paper-real", "paper-sim"), args
    _, s = settings("--thetas", "0,1", "--refine")  # a named set refined on request
    assert s["hypotheses"] == "adaptive" and s["thetas"] == "0,1" and s["betas"] == "adaptive"
    assert_input_error(invoke("live", "corridor", "--refine", "--expertise", "changing", "--port", 0),
                       "--refine")


@pytest.mark.slow
def test_next_start_command(tmp_path):
    demos = tmp_path / "demos.csv"
    ok(invoke("simulate", "crossroads", "--theta", "1,1,0,0,0", "--beta", "0.5", "--episodes", 2,
              "--out", demos))
    args = ("next-start", "crossroads", "--demos", demos, "--thetas", "0,1", "--samples", 16,
            "--candidates", 8, "--seed", 3)
    a, b = invoke(*args), invoke(*args)
    ok(a)
    assert a.stdout == b.stdout and a.stdout.startswith("next start: state ")
    assert "expected information gain" in a.stdout and "8 of" in a.stdout
    assert_input_error(invoke("next-start", "crossroads"), "--demos")
    adaptive = invoke(*(x for x in args if x not in ("--thetas", "0,1")))  # over the refined set
    ok(adaptive)
    assert adaptive.stdout.startswith("next start: state ") and adaptive.stdout != a.stdout
    assert_input_error(invoke(*args, "--target", "theta"), "--target")


# --------------------------------------------------------------------- floor plans
PLAN = """\
S.>>G
.x#..
.....
"""
#: A path from S to the goal with three turns (down, then right into the restricted cell, ...).
PLAN_MOVES = ("down", "right", "up", "right", "right", "right")
PLAN_AXES = ("v", "h", "v", "h", "h", "h")  # the heading each move leaves behind


@pytest.fixture
def plan_path(tmp_path):
    path = tmp_path / "plan.txt"
    path.write_text(PLAN)
    path.with_suffix(".toml").write_text('world = "warehouse"\ncell_size = 0.5\n')
    return path


@pytest.fixture(scope="module")
def hyp3():
    return HypothesisSet(theta_grid((0.0, 1.0), 3), BETA_PRESETS["paper-sim"])


def demo_rows(path) -> list[list[str]]:
    return [line.split(",") for line in path.read_text().splitlines()]


@pytest.mark.slow
def test_floor_plan_session_records_headings_and_resumes(tmp_path, plan_path, hyp3):
    from expertise_irl.plots.floorplan import CELL_COLORS, GOAL_FILL, ROAD_COLOR
    from expertise_irl.worlds.maps import resolve_world

    plan = resolve_world(plan_path)
    out = tmp_path / "rec"
    session, client = make(plan, hyp3, out)
    mdp = session.mdp
    assert mdp.state_heading is not None
    s0 = session.position
    letter0 = "hv"[int(mdp.state_heading[s0])]
    states = [s0]
    with client.websocket_connect(WS) as ws:
        init = ws.receive_json()
        assert init["map"]["world"] == "warehouse" and init["map"]["rows"] == PLAN.splitlines()
        assert init["colors"]["zones"]["x"] == CELL_COLORS["x"] and init["colors"]["arrow"] == ROAD_COLOR
        assert init["colors"]["goal"] == GOAL_FILL and init["actions"] == list(ACTION_NAMES)
        assert init["state"]["position"] == [0, 0] and init["state"]["heading"] == letter0
        assert "heading" in init["state"]["start"]["why"]
        for name, axis in zip(PLAN_MOVES[:-1], PLAN_AXES, strict=False):  # stop short of the goal
            r = move(ws, name)
            states.append(int(mdp.next_state[states[-1], ACTION_NAMES.index(name)]))
            assert r["event"] == "moved" and r["heading"] == axis
            assert r["position"] == mdp.state_xy[states[-1]].tolist()
    demos = out / "demos.csv"
    rows = demo_rows(demos)
    assert rows[0] == ["episode", "step", "x", "y", "heading"]
    assert [r[4] for r in rows[1:]] == [letter0, *PLAN_AXES[:-1]]
    assert [[int(v) for v in r[2:4]] for r in rows[1:]] == mdp.state_xy[states].tolist()
    trajs = read_demos_csv(demos, mdp)  # the heading column gives back the very states moved through
    assert trajs.state.tolist() == states[:-1]
    assert [ACTION_NAMES[a] for a in trajs.action] == list(PLAN_MOVES[:-1])
    expected = session.estimator.estimate
    del session, client

    again, client = make(plan, hyp3, out)  # resumed mid-episode, on the recorded start heading
    assert again.position == states[-1] and again.start.how == "resumed"
    assert again.estimator.estimate.beta_hat == pytest.approx(expected.beta_hat, abs=1e-12)
    with client.websocket_connect(WS) as ws:
        state = ws.receive_json()["state"]
        assert state["episode"] == 0 and state["step"] == len(PLAN_MOVES) - 1
        r = move(ws, PLAN_MOVES[-1])
        assert r["event"] == "episode_done" and r["episode"] == 1 and r["step"] == 0
        doc = json.loads((out / "result.json").read_text())
        assert doc["data"]["episodes"] == 1 and doc["data"]["actions"] == len(PLAN_MOVES)
        assert doc["feature_names"] == list(mdp.feature_names)
        assert doc["beta_hat"] == pytest.approx(r["estimate"]["beta_hat"])
    del again, client

    third, client = make(plan, hyp3, out)  # resumed between episodes: the next one is episode 1
    s = third.position
    a = next(a for a in range(4) if mdp.next_state[s, a] >= 0)
    with client.websocket_connect(WS) as ws:
        assert ws.receive_json()["state"]["episode"] == 1
        r = move(ws, ACTION_NAMES[a])
        assert r["episode"] == 1 and r["step"] == 1 and r["heading"] == "hv"[int(mdp.state_heading[
            mdp.next_state[s, a]])]
    rows = demo_rows(demos)
    assert [r[:2] for r in rows[-2:]] == [["1", "0"], ["1", "1"]]
    assert rows[-2][4] == "hv"[int(mdp.state_heading[s])]
    trajs = read_demos_csv(demos, mdp)
    assert trajs.n_episodes == 2 and trajs.state.tolist() == [*states, s]

    result = tmp_path / "infer.json"
    ok(invoke("infer", plan_path, "--demos", demos, "--out", result, "--thetas", "0,1"))
    assert json.loads(result.read_text())["data"]["actions"] == len(PLAN_MOVES) + 1


def test_floor_plan_directory_without_the_heading_column_is_refused(tmp_path, plan_path, hyp3):
    from expertise_irl.errors import InputError
    from expertise_irl.worlds.maps import resolve_world

    out = tmp_path / "rec"
    out.mkdir()
    (out / "demos.csv").write_text("episode,step,x,y\n0,0,0,0\n0,1,1,0\n")  # readable, not appendable
    with pytest.raises(InputError, match="appends rows episode,step,x,y,heading"):
        open_session(resolve_world(plan_path), hyp3, out)


def test_live_and_next_start_commands_on_a_floor_plan(tmp_path, plan_path, monkeypatch):
    import expertise_irl.live.server as server
    from expertise_irl.results import map_digest
    from expertise_irl.worlds.maps import resolve_world

    monkeypatch.setattr(server, "serve", lambda session, sock, on_ready: (
        on_ready(server.url_of(sock)), sock.close()))
    out = tmp_path / "rec"
    r = invoke("live", plan_path, "--thetas", "0,1", "--out", out, "--port", 0)
    ok(r)
    assert "live page: http://127.0.0.1:" in r.stdout and "plan.txt" in r.stdout
    doc = json.loads((out / "result.json").read_text())
    assert doc["settings"]["mdp_digest"] == map_digest(resolve_world(plan_path))
    demos = out / "demos.csv"
    demos.write_text("episode,step,x,y,heading\n0,0,0,0,h\n0,1,0,1,v\n")
    r = invoke("live", plan_path, "--thetas", "0,1", "--out", out, "--port", 0)
    ok(r)
    assert "resumed 1 episode, 1 action from" in r.stderr + r.stdout
    r = invoke("next-start", plan_path, "--demos", demos, "--thetas", "0,1", "--samples", 8, "--seed", 1)
    ok(r)
    assert r.stdout.startswith("next start: ") and "expected information gain" in r.stdout
    assert_input_error(invoke("live", tmp_path / "nosuch.txt", "--port", 0), "nosuch.txt")


def test_changing_expertise_reports_this_episodes_filtered_beta(tmp_path, zone_map, hyp):
    """``expertise="changing"``: every state message carries the current episode's β, the changing
    model filtered on the actions so far (none before the first action); a stationary session has none."""
    import numpy as np

    from expertise_irl.inference.changing import filtered_by_action

    session, _ = make(zone_map, hyp, tmp_path / "c", expertise="changing")
    assert session.state_message()["expertise_now"] is None
    for a in path_to_goal(session.mdp, session.position)[:3]:
        session.move(a)
    now = session.state_message()["expertise_now"]
    pairs = session.estimator._pairs
    step = np.stack([session.estimator._table[p[2], p[3]] for p in pairs])
    want = filtered_by_action(step, np.zeros(len(pairs), int), hyp)[-1]
    assert now["episode"] == 0 and now["beta_mean"] == pytest.approx(float(want @ hyp.betas), rel=1e-12)
    assert now["q05"] <= now["q95"]
    assert "expertise_now" not in make(zone_map, hyp, tmp_path / "s")[0].state_message()


# --------------------------------------------------------------------- adaptive sets
def make_adaptive(zone_map, out):
    """A session with no set named: the coarse start set, refined after each episode."""
    from expertise_irl.inference.methods import DiscreteOptions

    opts = DiscreteOptions()
    assert opts.refines
    return make(zone_map, opts.hypotheses(5), out, refine=opts)


def refined_directly(mdp, trajs):
    """``infer``'s adaptive set and posterior for ``trajs``, computed without the session."""
    from expertise_irl.inference.adaptive import refine, start_resolution, start_set

    K = mdp.n_features
    r = refine(mdp, trajs, start_set(K), theta_step=1 / start_resolution(K))
    return r, DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior).update(trajs)


def drive_episode(ws, session) -> tuple[dict, dict]:
    """Drive from the session's position to the goal; the two replies to the last move."""
    actions = path_to_goal(session.mdp, session.position)
    for a in actions[:-1]:
        r = move(ws, ACTION_NAMES[a])
        assert r["event"] == "moved" and r["n_hypotheses"] == len(session.estimator.hypotheses)
    return move(ws, ACTION_NAMES[actions[-1]]), ws.receive_json()


@pytest.mark.slow
def test_an_adaptive_session_refines_its_set_after_each_episode(tmp_path, zone_map):
    from expertise_irl.inference.adaptive import start_set

    session, client = make_adaptive(zone_map, tmp_path)
    mdp = session.mdp
    start = start_set(mdp.n_features)
    assert np.array_equal(session.estimator.hypotheses.theta, start.theta)
    assert np.array_equal(session.estimator.hypotheses.beta, start.beta)
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        for episode in range(2):
            n_before = len(session.history_beta)
            shown, r = drive_episode(ws, session)
            # The goal is shown at once, with the refinement announced; the new set comes next.
            assert shown["event"] == "refining" and "Refining the hypothesis set" in shown["message"]
            assert shown["episodes_done"] == episode + 1 and shown["episode"] == episode
            assert len(shown["path"]) > 1 and shown["path"][-1] == shown["position"]  # at the goal
            assert r["path"] == [r["position"]] and r["episode"] == episode + 1  # at the next start
            assert r["event"] == "episode_done" and "The hypothesis set was refined to" in r["message"]
            trajs = read_demos_csv(tmp_path / "demos.csv", mdp)
            want_set, want = refined_directly(mdp, trajs)
            got = session.estimator.hypotheses
            assert np.array_equal(got.theta, want_set.hypotheses.theta)
            assert np.array_equal(got.beta, want_set.hypotheses.beta)
            assert len(got) != len(start)  # refined, not the start set again
            assert np.allclose(session.estimator.belief().probabilities, want.probabilities,
                               rtol=1e-9, atol=1e-12)
            assert r["estimate"]["beta_hat"] == pytest.approx(want.mean_beta, rel=1e-9)
            assert r["n_hypotheses"] == len(got)
            assert len(session.history_beta) == n_before + len(path_to_goal(mdp, trajs.state[n_before]))
            doc = json.loads((tmp_path / "result.json").read_text())
            assert doc["refinement"]["n_hypotheses"] == len(got) == doc["settings"]["n_hypotheses"]
            assert doc["beta_hat"] == pytest.approx(want.mean_beta, rel=1e-9)
            assert doc["live"]["history"]["beta_hat"] == session.history_beta
    # result.json is infer's result on demos.csv (same set, same posterior).
    (tmp_path / "small.txt").write_text(MAP)
    ok(invoke("infer", tmp_path / "small.txt", "--demos", tmp_path / "demos.csv",
              "--out", tmp_path / "i.json"))
    doc, inferred = (json.loads((tmp_path / n).read_text()) for n in ("result.json", "i.json"))
    assert inferred["settings"]["hypotheses"] == "adaptive"
    assert inferred["refinement"]["betas"] == doc["refinement"]["betas"]
    assert inferred["beta_hat"] == pytest.approx(doc["beta_hat"], rel=1e-9)
    assert inferred["theta_hat"] == pytest.approx(doc["theta_hat"], rel=1e-9)
    # What the page showed during episode 0 was the posterior over the start set.
    ep0 = read_demos_csv(tmp_path / "demos.csv", mdp).episodes()[0]
    n0 = len(ep0[1])
    coarse = DiscreteBelief.from_mdp(mdp, start).trace(read_demos_csv(tmp_path / "demos.csv", mdp))
    assert session.history_beta[:n0] == pytest.approx(coarse.mean_beta[1:n0 + 1].tolist(), rel=1e-9)
    assert session.history_beta[n0:] != pytest.approx(coarse.mean_beta[n0 + 1:].tolist(), rel=1e-6)


@pytest.mark.slow
def test_an_adaptive_session_resumes_on_the_same_set_and_belief(tmp_path, zone_map):
    session, client = make_adaptive(zone_map, tmp_path)
    mdp = session.mdp
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        drive_episode(ws, session)
        drive_episode(ws, session)
        between = (session.estimator.hypotheses, session.estimator.estimate, list(session.history_beta))
        move(ws, ACTION_NAMES[path_to_goal(mdp, session.position)[0]])  # episode 2 cut off
    est, record = session.estimator, session.refined.record
    del session, client
    again, _ = make_adaptive(zone_map, tmp_path)  # replays demos.csv: refines from episodes 0 and 1
    assert again.estimator.episode_open and again.start.how == "resumed"
    assert np.array_equal(again.estimator.hypotheses.theta, est.hypotheses.theta)
    assert np.array_equal(again.estimator.hypotheses.beta, est.hypotheses.beta)
    assert np.allclose(again.estimator.belief().probabilities, est.belief().probabilities,
                       rtol=1e-9, atol=1e-12)
    assert again.estimator.estimate.beta_hat == pytest.approx(est.estimate.beta_hat, abs=1e-12)
    assert again.history_beta == pytest.approx(between[2] + [est.estimate.beta_hat], rel=1e-9)
    # Refined from the same (finished) episodes: every round's estimate as when they were recorded.
    def rounds(rec):
        return [{k: v for k, v in entry.items() if k != "seconds"} for entry in rec["rounds"]]

    assert rounds(again.refined.record) == rounds(record) and len(rounds(record)) >= 2
    # Stopped between episodes: the same set and estimate as when episode 1 ended.
    cut = tmp_path / "between"
    cut.mkdir()
    rows = (tmp_path / "demos.csv").read_text().splitlines()
    (cut / "demos.csv").write_text("\n".join(r for r in rows if not r.startswith("2,")) + "\n")
    third, _ = make_adaptive(zone_map, cut)
    assert not third.estimator.episode_open
    assert len(third.history_beta) == third.estimator.n_observed  # no result.json: redrawn
    assert np.array_equal(third.estimator.hypotheses.beta, between[0].beta)
    assert third.estimator.estimate.beta_hat == pytest.approx(between[1].beta_hat, abs=1e-12)


def test_a_named_set_is_not_refined(tmp_path, zone_map, hyp):
    session, client = make(zone_map, hyp, tmp_path)
    with client.websocket_connect(WS) as ws:
        ws.receive_json()
        for a in path_to_goal(session.mdp, session.position):
            r = move(ws, ACTION_NAMES[a])
        assert r["event"] == "episode_done" and "refined" not in r["message"]
    assert session.estimator.hypotheses is hyp and session.refine is None
    doc = json.loads((tmp_path / "result.json").read_text())
    assert "refinement" not in doc and "history" not in doc["live"]
    assert doc["settings"] == {"command": "live", "mdp_digest": "sha256:x"}
