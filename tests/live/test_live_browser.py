"""End to end in a real headless Chromium (Debian's ``chromium``, driven by Python Playwright):
start ``expertise-irl live``, drive an episode to the goal with key presses, check that the shown
β̂ changes after every action, that ``demos.csv`` holds exactly those actions, that a move into a
wall is refused and not recorded, and that the real server refuses path traversal; a large floor
plan fills the window.

The test saves a screenshot of the page mid-episode in its temporary directory; with
``EXPERTISE_IRL_SCREENSHOT=PATH`` it also copies it there (that is how ``docs/images/live.png``
is made).
"""

from __future__ import annotations

import http.client
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
from goal_paths import path_to_goal

from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.mdp import ACTION_NAMES
from expertise_irl.worlds.zones import parse_map

CHROMIUM = shutil.which("chromium")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed "
                                "(apt-get install -y chromium; .ci/run installs it)")

MAP = """\
......xx....
..ss..xx..#.
..ss......#.
>>>>>>>>>>>v
.....tt....v
.....tt....v
...........G
"""
#: Keys used for each action, alternating between the arrows and WASD.
KEYS = {"up": ("ArrowUp", "w"), "down": ("ArrowDown", "s"), "left": ("ArrowLeft", "a"),
        "right": ("ArrowRight", "d")}
SERVER_START_S = 180  # the solve compiles JAX kernels on first use; generous for a loaded CI machine


@contextmanager
def serving(map_path, out, *extra, named: bool = True):
    """``expertise-irl live MAP --out OUT`` on a free port (``named``: with the set ``--thetas 0,1``;
    else the adaptive default); yields its URL, stops it with Ctrl-C."""
    exe = Path(sys.executable).with_name("expertise-irl")
    proc = subprocess.Popen(
        [str(exe), "live", str(map_path), *(("--thetas", "0,1") if named else ()), "--out", str(out),
         "--port", "0", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "COLUMNS": "200"})
    url = None
    deadline = time.monotonic() + SERVER_START_S
    try:
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            m = re.search(r"live page: (http://127\.0\.0\.1:\d+/)", line)
            if m:
                url = m.group(1)
                break
        assert url, f"server did not start: {proc.stderr.read() if proc.poll() is not None else ''}"
        yield url
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, "Ctrl-C should stop the server cleanly"
    assert "stopped:" in proc.stdout.read()


@pytest.fixture
def server(tmp_path):
    map_path = tmp_path / "room.txt"
    map_path.write_text(MAP)
    out = tmp_path / "rec"
    with serving(map_path, out) as url:
        yield url, map_path, out


def raw_get(url: str, path: str) -> tuple[int, bytes]:
    host, port = url.split("//")[1].rstrip("/").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=10)
    conn.request("GET", path)  # sent exactly as written: no client-side normalisation of ".."
    r = conn.getresponse()
    return r.status, r.read()


@contextmanager
def live_page(sync_api, url: str):
    """The live page in headless Chromium, loaded and waiting: ``(page, errors)``, where
    ``errors`` collects the page's uncaught JavaScript errors."""
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--headless", "--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1180, "height": 880})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url)
            # expect() waits without evaluating strings (the page's CSP forbids eval)
            sync_api.expect(page.locator("#actions")).to_have_attribute("data-value", "0", timeout=30_000)
            yield page, errors
        finally:
            browser.close()


@pytest.mark.slow
def test_drive_an_episode_in_chromium(server, tmp_path):
    sync_api = pytest.importorskip("playwright.sync_api", reason="Python playwright is not installed")
    url, map_path, out = server
    mdp = parse_map(MAP, name=str(map_path)).to_mdp()
    index = parse_map(MAP).state_index()
    shot = tmp_path / "live.png"
    expect = sync_api.expect
    with live_page(sync_api, url) as (page, errors):
        assert page.locator("#beta-bars .track").count() == 6  # one bar per β of paper-sim
        assert page.locator("#theta-bars .track").count() == 5
        assert page.locator("#group-bars .track").count() == 3
        assert "The robot chose" in page.locator("#start").inner_text()
        assert page.locator("#teaching-line").is_hidden()  # maxent: no teaching reading
        x, y = map(int, re.findall(r"-?\d+", page.locator("#position").get_attribute("data-value")))
        start = int(index[y, x])
        actions = path_to_goal(mdp, start)
        assert len(actions) >= 3

        wall = next(a for a in range(4) if mdp.next_state[start, a] < 0)
        page.keyboard.press(KEYS[ACTION_NAMES[wall]][0])  # into a wall or off the map
        expect(page.locator("#message")).to_have_class(re.compile("refused"))
        assert "not recorded" in page.locator("#message").inner_text()
        assert page.locator("#actions").get_attribute("data-value") == "0"

        shown = [page.locator("#beta-hat").inner_text()]
        for i, a in enumerate(actions):
            key = KEYS[ACTION_NAMES[a]][i % 2]
            page.keyboard.press(key)
            done = i + 1 == len(actions)
            want = "1" if done else "0"
            expect(page.locator("#actions")).to_have_attribute("data-value", str(i + 1), timeout=30_000)
            expect(page.locator("#episodes-done")).to_have_attribute("data-value", want)
            shown.append(page.locator("#beta-hat").inner_text())
            assert shown[-1] != shown[-2], f"β̂ did not change after action {i + 1}: {shown}"
            if i == len(actions) // 2:
                page.screenshot(path=str(shot))
        assert not errors, errors
        assert "(episode 0 done;" in page.locator("#message").inner_text()
        assert page.locator("#episode").get_attribute("data-value") == "1"  # demos.csv's numbering
        assert not errors, errors
    assert shot.stat().st_size > 10_000
    if os.environ.get("EXPERTISE_IRL_SCREENSHOT"):
        shutil.copyfile(shot, os.environ["EXPERTISE_IRL_SCREENSHOT"])

    trajs = read_demos_csv(out / "demos.csv", mdp)
    assert trajs.state[0] == start and trajs.action.tolist() == actions
    assert (out / "result.json").is_file()

    for path in ("/static/../session.py", "/static/..%2fsession.py", "/static/%2e%2e/server.py",
                 "/static/..%2f..%2f..%2f..%2fpyproject.toml", "/../../etc/passwd"):
        status, body = raw_get(url, path)
        assert status in (400, 404), (path, status)
        assert b"import" not in body and b"root:" not in body
    assert raw_get(url, "/static/live.js")[0] == 200


@pytest.mark.slow
def test_changing_expertise_shows_this_episodes_beta_in_chromium(tmp_path):
    """``live --expertise changing``: the page shows the current episode's β (filtered) beside β̂,
    and it follows the moves."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="Python playwright is not installed")
    map_path = tmp_path / "room.txt"
    map_path.write_text(MAP)
    mdp = parse_map(MAP, name=str(map_path)).to_mdp()
    index = parse_map(MAP).state_index()
    expect = sync_api.expect
    with serving(map_path, tmp_path / "rec", "--expertise", "changing") as url, \
            live_page(sync_api, url) as (page, errors):
        expect(page.locator("#beta-now-line")).to_be_visible()
        assert page.locator("#beta-now").inner_text() == "–"  # nothing driven yet
        x, y = map(int, re.findall(r"-?\d+", page.locator("#position").get_attribute("data-value")))
        actions = path_to_goal(mdp, int(index[y, x]))
        shown = []
        for i, a in enumerate(actions[:3]):
            page.keyboard.press(KEYS[ACTION_NAMES[a]][0])
            expect(page.locator("#actions")).to_have_attribute("data-value", str(i + 1), timeout=30_000)
            shown.append(page.locator("#beta-now").inner_text())
        assert all(re.match(r"[\d.e+-]+ \(90%: .+–.+, episode 0\)", t) for t in shown), shown
        assert len(set(shown)) > 1, shown
        assert not errors, errors


@pytest.mark.slow
def test_the_teaching_model_reads_teaching_or_doing_in_chromium(tmp_path):
    """``live --model pedagogical``: the page reads the demonstrations as teaching, doing or undecided
    after every action, and at the goal its reading is the one result.json records."""
    import json

    sync_api = pytest.importorskip("playwright.sync_api", reason="Python playwright is not installed")
    map_path, out = tmp_path / "room.txt", tmp_path / "rec"
    map_path.write_text(MAP)
    mdp = parse_map(MAP, name=str(map_path)).to_mdp()
    index = parse_map(MAP).state_index()
    expect = sync_api.expect
    with serving(map_path, out, "--model", "pedagogical") as url, live_page(sync_api, url) as (page, errors):
        expect(page.locator("#teaching-line")).to_be_visible()
        assert page.locator("#teaching").inner_text().startswith("the demonstrations do not tell teaching")
        x, y = map(int, re.findall(r"-?\d+", page.locator("#position").get_attribute("data-value")))
        actions = path_to_goal(mdp, int(index[y, x]))
        shown = []
        for i, a in enumerate(actions):
            page.keyboard.press(KEYS[ACTION_NAMES[a]][i % 2])
            expect(page.locator("#actions")).to_have_attribute("data-value", str(i + 1), timeout=30_000)
            shown.append(page.locator("#teaching").inner_text())
        line = re.compile(r"\(2 log BF = -?[\d.]+\).*; λ̂ = [\d.e+-]+ \(90%: .+–.+\)$")
        assert all(line.search(t) for t in shown), shown
        assert len(set(shown)) > 1, shown
        expect(page.locator("#episodes-done")).to_have_attribute("data-value", "1")
        record = json.loads((out / "result.json").read_text())["teaching"]
        assert shown[-1].startswith(record["reading"] + "; ")
        assert page.locator("#teaching").get_attribute("data-verdict") == record["verdict"]
        assert not errors, errors


@pytest.mark.slow
def test_an_adaptive_set_is_refined_after_an_episode_in_chromium(tmp_path):
    """No set named: the page starts on the coarse start set, shows the refined set (its β bars and
    size) once an episode ends, and the next episode is driven over it."""
    import json

    from expertise_irl.inference.adaptive import START_BETAS, start_set

    sync_api = pytest.importorskip("playwright.sync_api", reason="Python playwright is not installed")
    map_path, out = tmp_path / "room.txt", tmp_path / "rec"
    map_path.write_text(MAP)
    mdp = parse_map(MAP, name=str(map_path)).to_mdp()
    index = parse_map(MAP).state_index()
    expect = sync_api.expect

    def here() -> int:
        x, y = map(int, re.findall(r"-?\d+", page.locator("#position").get_attribute("data-value")))
        return int(index[y, x])

    with serving(map_path, out, named=False) as url, live_page(sync_api, url) as (page, errors):
        assert page.locator("#beta-bars .track").count() == len(START_BETAS)
        assert f"({len(start_set(5))} hypotheses)" in page.locator("#entropy").inner_text()
        actions = path_to_goal(mdp, here())
        for i, a in enumerate(actions):
            page.keyboard.press(KEYS[ACTION_NAMES[a]][i % 2])
            expect(page.locator("#actions")).to_have_attribute("data-value", str(i + 1), timeout=30_000)
        expect(page.locator("#message")).to_contain_text("The hypothesis set was refined to", timeout=120_000)
        rec = json.loads((out / "result.json").read_text())["refinement"]
        assert f"({rec['n_hypotheses']} hypotheses)" in page.locator("#entropy").inner_text()
        assert page.locator("#beta-bars .track").count() == rec["n_beta"] != len(START_BETAS)
        a = path_to_goal(mdp, here())[0]
        page.keyboard.press(KEYS[ACTION_NAMES[a]][0])
        expect(page.locator("#actions")).to_have_attribute("data-value", str(len(actions) + 1),
                                                          timeout=30_000)
        assert page.locator("#episode").get_attribute("data-value") == "1"
        assert not errors, errors


PLAN = """\
S...xx.....
>>>>>>>>>v.
....##...v.
.xx.##...v.
.xx......G.
"""
PLAN_MOVES = ["down"] + ["right"] * 9 + ["down"] * 3  # along the road, turning twice


@pytest.mark.slow
def test_drive_a_floor_plan_in_chromium(tmp_path):
    """A warehouse floor plan: drawn, driven with turns, recorded with the heading column."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="Python playwright is not installed")
    map_path = tmp_path / "plan.txt"
    map_path.write_text(PLAN)
    map_path.with_suffix(".toml").write_text('world = "warehouse"\ncell_size = 0.5\n')
    out = tmp_path / "rec"
    shot = tmp_path / "live-plan.png"
    expect = sync_api.expect
    with serving(map_path, out) as url, live_page(sync_api, url) as (page, errors):
        assert page.locator("#theta-bars .track").count() == 3  # length, restricted, road
        start_heading = page.locator("#heading").get_attribute("data-value")
        for i, name in enumerate(PLAN_MOVES):
            page.keyboard.press(KEYS[name][i % 2])
            expect(page.locator("#actions")).to_have_attribute("data-value", str(i + 1), timeout=30_000)
            if i + 1 < len(PLAN_MOVES):
                axis = "vertical" if name == "down" else "horizontal"
                expect(page.locator("#heading")).to_have_attribute("data-value", axis)
            if i == 5:
                page.screenshot(path=str(shot))
        expect(page.locator("#episodes-done")).to_have_attribute("data-value", "1")
        assert not errors, errors
    assert shot.stat().st_size > 10_000
    rows = [line.split(",") for line in (out / "demos.csv").read_text().splitlines()]
    assert rows[0] == ["episode", "step", "x", "y", "heading"]
    first = {"horizontal": "h", "vertical": "v"}[start_heading]
    assert [r[4] for r in rows[1:]] == [first] + ["v" if m == "down" else "h" for m in PLAN_MOVES]


@pytest.mark.slow
def test_a_large_floor_plan_fills_the_window(tmp_path):
    """The bundled study's 67×40 floor plan gets comfortable cells at 1280×800 (the map fills the
    space beside the estimate), and follows the window when it is resized."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="Python playwright is not installed")
    from importlib import resources

    plan = Path(str(resources.files("expertise_irl") / "userstudy" / "example" / "spec-a.txt"))
    with serving(plan, tmp_path / "rec") as url, live_page(sync_api, url) as (page, errors):
        page.set_viewport_size({"width": 1280, "height": 800})
        canvas, panel = page.locator("#map"), page.locator("section.right")
        sync_api.expect(canvas).to_have_attribute("data-cell", re.compile(r"^(1[4-9]|[2-5]\d)$"))  # ≥ 14 px
        cell, box, side = int(canvas.get_attribute("data-cell")), canvas.bounding_box(), panel.bounding_box()
        assert box["width"] == 67 * cell and box["height"] == 40 * cell
        assert side["x"] > box["x"] + box["width"] and side["x"] + side["width"] <= 1280  # beside it
        assert box["y"] + box["height"] < 800  # and the whole map on screen
        page.set_viewport_size({"width": 700, "height": 600})  # too narrow: the panel goes below
        sync_api.expect(canvas).to_have_attribute("data-cell", "9")
        assert panel.bounding_box()["y"] > canvas.bounding_box()["y"] + 40 * 9
        assert not errors, errors
