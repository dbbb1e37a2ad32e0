"""Recordings: ``discretise`` (a Cartesian recording → demonstrations CSV and a PNG to inspect) and
``simulate-recordings`` (a simulated person's tele-operation log)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError, plural
from ._app import (
    GoalRewardOption,
    ModelOption,
    _map_files,
    _note,
    _say,
    app,
    handles_errors,
    with_goal_reward,
)

#: Options shared with the commands that ingest recordings.
RateOption = Annotated[float, typer.Option(
    "--rate", help="Ticks per second: at each tick t0 + k/rate the last sample at or before it is "
    "kept (the paper's 1 Hz).")]
MaxDtOption = Annotated[float | None, typer.Option(
    "--max-dt", help="Seconds between two consecutive kept samples beyond which they are a gap "
    "(default: 2/rate).")]
FillGapsOption = Annotated[bool, typer.Option(
    "--fill-gaps", help="Fill gaps with a shortest free path (counted) instead of stopping with an error.")]
SnapOption = Annotated[bool, typer.Option(
    "--snap", help="Move samples outside the map or inside obstacles to the nearest free cell "
    "(counted) instead of stopping with an error.")]
_BAG = "ROS bag: "


def load_floor_plan_arg(map_spec: str):
    """The floor plan a MAP argument names; a zone map is refused with the reason."""
    from ..worlds.maps import resolve_world
    from ..worlds.warehouse import WarehouseMap

    plan = resolve_world(map_spec)
    if not isinstance(plan, WarehouseMap):
        raise InputError(f"{map_spec}: is a zone map; recordings need a warehouse floor plan "
                         "(a TOML beside it with world = \"warehouse\" and cell_size)")
    return plan


@app.command()
@handles_errors
def discretise(
    map_spec: Annotated[str, typer.Argument(
        metavar="MAP", help="Warehouse floor plan (.txt with its TOML).")],
    recording: Annotated[Path, typer.Option(
        help="Recording: a CSV episode,t,x,y (seconds, metres), or a ROS bag (.bag, .db3, .mcap or a "
        "ROS 2 bag folder) with --topic.")],
    out_path: Annotated[Path, typer.Option(
        "--out", help="Output demonstrations CSV (episode,step,x,y,heading).")],
    png: Annotated[Path | None, typer.Option(
        help="Figure of the samples against the cells (default: --out with .png).")] = None,
    rate: RateOption = 1.0,
    max_dt: MaxDtOption = None,
    fill_gaps: FillGapsOption = False,
    snap: SnapOption = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the outputs if they exist.")] = False,
    topic: Annotated[str | None, typer.Option(
        help=_BAG + "the topic of the positions: nav_msgs/msg/Odometry, geometry_msgs/msg/PoseStamped, "
        "geometry_msgs/msg/PoseWithCovarianceStamped or tf2_msgs/msg/TFMessage.")] = None,
    child: Annotated[str | None, typer.Option(
        help=_BAG + "on a tf topic, the robot's frame (the transforms' child_frame_id).")] = None,
    parent: Annotated[str | None, typer.Option(
        help=_BAG + "on a tf topic, the floor plan's frame (the transforms' header.frame_id; direct "
        "transforms only).")] = None,
    frame: Annotated[str | None, typer.Option(
        help=_BAG + "a pose message whose header.frame_id is not this is an error.")] = None,
    clock: Annotated[str, typer.Option(
        help=_BAG + "time from the message's header stamp (header) or the bag's receive time "
        "(receive).")] = "header",
    episode_topic: Annotated[str | None, typer.Option(
        help=_BAG + "each message on this std_msgs Int32/String/Empty topic starts a new episode "
        "(default: one episode per bag).")] = None,
    episode_gap: Annotated[float | None, typer.Option(
        help=_BAG + "more seconds than this between two samples start a new episode.")] = None,
) -> None:
    """Turn a Cartesian recording into demonstrations on a floor plan, and draw what was done.

    Samples are mapped to cells, resampled at --rate, repeats dropped, diagonal steps split,
    and each state's heading set from the move into it (docs/user-studies.md). Gaps and
    samples off the free cells stop with an error unless --fill-gaps / --snap; what they
    changed is counted and printed. A ROS bag gives the same samples from the positions on
    --topic (docs/user-studies.md, "ROS bags").
    """
    from ..demos.csv_io import write_demos_csv
    from ..demos.recordings import discretise_recording
    from ..demos.rosbag import BagOptions
    from ..plots.floorplan import render_discretised_png
    from ..results import check_writable
    from .core import _check_figure_format

    png = png if png is not None else out_path.with_suffix(".png")
    inputs = [*_map_files(map_spec), recording]
    for p in (out_path, png):
        check_writable(p, force=force, inputs=inputs)
    if png.resolve() == out_path.resolve():
        raise InputError(f"{png}: the figure and the demonstrations would be the same file")
    _check_figure_format(png)
    plan = load_floor_plan_arg(map_spec)
    bag = BagOptions(topic=topic, child=child, parent=parent, frame=frame, clock=clock,
                     episode_topic=episode_topic, episode_gap=episode_gap)
    result = discretise_recording(recording, plan, rate=rate, max_dt=max_dt, fill_gaps=fill_gaps,
                                  snap=snap, bag=bag)
    write_demos_csv(out_path, result.trajectories, plan.to_mdp(), fmt="grid")
    render_discretised_png(png, plan, result, title=f"{recording} on {plan.name}")
    for ep in result.episodes:
        end = "reached a goal" if ep.reached_goal else "ended before a goal"
        _say(f"episode {ep.episode}: {len(ep.samples_xy)} samples, {len(ep.kept)} kept at "
             f"{result.rate:g} Hz, {plural(ep.moves, 'move')}, {end}; filled gaps {ep.filled_gaps}, "
             f"snapped samples {ep.snapped_samples}")
        if ep.after_goal:
            _note(f"episode {ep.episode}: the robot drove on after entering a goal; "
                  f"{ep.after_goal} kept samples after it ignored (a goal ends the episode)")
    _say(f"wrote {out_path} and {png}: {plural(len(result.episodes), 'episode')}, "
         f"{plural(len(result.trajectories), 'move')}; "
         f"filled gaps {result.filled_gaps}, snapped samples {result.snapped_samples}")


@app.command("simulate-recordings")
@handles_errors
def simulate_recordings_cmd(
    map_spec: Annotated[str, typer.Argument(
        metavar="MAP", help="Warehouse floor plan (.txt with its TOML) or a bundled floor plan.")],
    theta: Annotated[str, typer.Option(help="Preferences θ*, comma-separated (normalised to unit l1).")],
    beta: Annotated[float, typer.Option(help="Expertise temperature β* > 0 (small = expert).")],
    out_path: Annotated[Path, typer.Option(
        "--out", help="Output recording CSV: episode,t,x,y; or, named .bag, .db3 or .mcap, a ROS bag of the "
        "same samples (nav_msgs/msg/Odometry on /odom, each episode starting with a message on /episode).")],
    episodes: Annotated[int, typer.Option(min=1, help="Number of episodes.")] = 1,
    seed: Annotated[int, typer.Option(min=0, help="Random seed (moves, timing, noise, gaps).")] = 0,
    max_steps: Annotated[int, typer.Option(min=1, help="Episode length cap (moves).")] = 500,
    model: ModelOption = "maxent",
    hz: Annotated[float, typer.Option(help="Samples per second.")] = 10.0,
    speed: Annotated[float | None, typer.Option(
        help="Driving speed in m/s (default 0.8 cells per second, so 1 Hz sees every cell).")] = None,
    noise: Annotated[float, typer.Option(
        help="Standard deviation of the position noise, metres per axis.")] = 0.03,
    pause_prob: Annotated[float, typer.Option(
        help="Probability of a pause after arriving at a cell.")] = 0.05,
    pause_s: Annotated[float, typer.Option(help="Mean length of a pause (seconds; uniform on ±50%).")] = 2.0,
    gaps: Annotated[int, typer.Option(min=0, help="Stretches with no samples (a logger drop-out).")] = 0,
    gap_s: Annotated[float, typer.Option(help="Length of each gap (seconds).")] = 3.0,
    demos: Annotated[Path | None, typer.Option(
        help="Also write the moves the person chose (episode,step,x,y,heading), to compare with "
        "discretise.")] = None,
    goal_reward: GoalRewardOption = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the outputs if they exist.")] = False,
) -> None:
    """Simulate a person on a floor plan and record the robot in metres, as a tele-operation log.

    The person chooses moves by --model with θ* and β*; the robot drives them from cell
    centre to cell centre at --speed, pauses now and then, is sampled at --hz with Gaussian
    --noise, and --gaps stretches of --gap-s seconds lose their samples (docs/user-studies.md).
    """
    import numpy as np

    from ..demos.csv_io import write_demos_csv
    from ..results import check_writable
    from ..userstudy.simulated_recordings import RobotMotion, simulate_recordings, write_recording
    from ._app import _check_beta, _check_model, _parse_theta, _report_capped

    inputs = _map_files(map_spec)
    for p in (out_path, demos):
        if p is not None:
            check_writable(p, force=force, inputs=inputs)
    if demos is not None and demos.resolve() == out_path.resolve():
        raise InputError(f"{demos}: the recording and the demonstrations would be the same file")
    plan = with_goal_reward(load_floor_plan_arg(map_spec), goal_reward)
    mdp = plan.to_mdp()
    th = _parse_theta(theta, mdp.n_features, mdp.feature_names, fixed_reward=mdp.has_offset)
    _check_beta(beta)
    _check_model(model)
    motion = RobotMotion(hz=hz, speed=speed, noise=noise, pause_prob=pause_prob, pause_s=pause_s,
                         gaps=gaps, gap_s=gap_s)
    recs, trajs = simulate_recordings(plan, th, beta, episodes, np.random.default_rng(seed), motion=motion,
                                      max_steps=max_steps, model=model)
    n = write_recording(out_path, recs)
    if demos is not None:
        write_demos_csv(demos, trajs, mdp, fmt="grid")
    _say(f"wrote {out_path}: {plural(len(recs), 'episode')}, {plural(n, 'sample')} at {hz:g} Hz, "
         f"{plural(len(trajs), 'move')} "
         f"(θ*={np.round(th, 4).tolist()}, β*={beta:g}, model {model}; {gaps} gaps)"
         + (f"; moves in {demos}" if demos is not None else ""))
    _report_capped(trajs, mdp, max_steps, model)
