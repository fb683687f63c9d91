"""The Python environment's speed next to `mrdrive run`'s: one episode, driven the same way.

    python bench/env_speed.py [--scenario scenarios/default.toml] [--scale 0.75] [--seed 1] [--repeats 3]

What is compared. Both sides drive the same episode with the same driver: the privileged
expert. `mrdrive run SCENARIO --expert --scale S --seed N` drives it in Rust; the
environment (`MrdriveEnv(SCENARIO, scale=S)`, `reset(seed=N)`) replays, step by step, the
controls that expert computed at each control boundary, read from the MCAP log of one
reference run (`--record --no-images`, not timed). The loop is deterministic, so the
environment's episode is the expert's run tick for tick; the script checks that the two
result records agree (success, completion, infraction counts, simulated time, ticks) and
stops otherwise. Each side prints simulated seconds per wall second (the real-time
factor), with the camera rig and without a camera, medians of `--repeats` runs.

The camera's work is the same on both sides when the control boundaries fall on the
camera's frames: `mrdrive run --camera` renders every camera frame (20 Hz), the
environment renders one observation per control boundary. In the default scenario that
holds at 0.75x (Tc = 50 ms, a 50 ms latency); at 1.0x its 100 ms latency makes the
boundaries 10 Hz, so the environment would render half the frames. The script prints
both counts and warns when they differ.

Needs numpy, gymnasium and mcap (the `.venv` that `cargo xtask setup` makes has them) and
a release build (`cargo build --release`, or MRDRIVE_BIN).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from mrdrive_gym import MrdriveEnv  # noqa: E402
from mrdrive_gym.client import find_binary  # noqa: E402

#: The result fields that must agree for the two sides to have driven one episode.
SAME_EPISODE = ("success", "completion_pct", "counts", "termination", "sim_time_s", "ticks")


def run_cmd(scenario: str, scale: float, seed: int, *extra: str) -> list[str]:
    """`mrdrive run` of the scenario driven by the expert at a fixed scale and seed."""
    return [
        find_binary(), "run", scenario, "--expert", "--scale", str(scale), "--seed", str(seed),
        "--quiet", *extra,
    ]


def expert_controls(scenario: str, scale: float, seed: int) -> tuple[list[list[float]], dict, int]:
    """One reference run of the expert, recorded: the controls it computed at each control
    boundary (in order, as the f32 values the loop used), its result, and the number of
    camera frames of the run (what `--camera` renders)."""
    from mcap.reader import make_reader  # the .venv of `cargo xtask setup` has it

    with tempfile.TemporaryDirectory() as d:
        log, out = Path(d) / "expert.mcap", Path(d) / "expert.json"
        cmd = run_cmd(scenario, scale, seed, "--json", str(out), "--record", str(log), "--no-images")
        subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        controls, frames = [], 0
        with open(log, "rb") as f:
            for _, channel, message in make_reader(f).iter_messages(topics=["/control", "/ego"]):
                if channel.topic == "/ego":
                    frames += 1  # written at every camera frame
                    continue
                computed = json.loads(message.data)["computed"]
                if computed is not None:
                    controls.append([computed["steer"], computed["throttle"], computed["brake"]])
        return controls, json.loads(out.read_text())["result"], frames


def same_episode(a: dict, b: dict) -> dict[str, tuple]:
    """The fields of SAME_EPISODE in which two results differ (empty: the same episode)."""
    return {k: (a.get(k), b.get(k)) for k in SAME_EPISODE if a.get(k) != b.get(k)}


def rust_rtf(scenario: str, scale: float, seed: int, camera: bool) -> tuple[float, dict]:
    """`mrdrive run --expert`: its real-time factor and its result."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "run.json"
        cmd = run_cmd(scenario, scale, seed, "--json", str(out), *(["--camera"] if camera else []))
        subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        record = json.loads(out.read_text())
        return record["perf"]["real_time_factor"], record["result"]


def env_replay(
    scenario: str, scale: float, seed: int, controls: list[list[float]], camera: bool
) -> tuple[float, float, dict, int]:
    """The environment driven by the expert's controls: its real-time factor, steps per
    second, result and number of steps (one rendered observation each with the camera)."""
    env = MrdriveEnv(scenario, scale=scale, camera=camera)
    try:
        t0 = time.perf_counter()
        env.reset(seed=seed)
        steps, done, info = 0, False, {}
        while not done:
            # Past the recorded boundaries (only if the episodes differ): hold the last control.
            control = controls[min(steps, len(controls) - 1)]
            _, _, term, trunc, info = env.step(control)
            steps += 1
            done = term or trunc
        wall = time.perf_counter() - t0
        result = info["record"]["result"]
        return result["sim_time_s"] / wall, steps / wall, result, steps
    finally:
        env.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="scenarios/default.toml")
    p.add_argument("--scale", type=float, default=0.75, help="the fixed input scale of both sides")
    p.add_argument("--seed", type=int, default=1, help="the traffic seed of both sides")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    scenario = str((ROOT / a.scenario).resolve())
    controls, reference, frames = expert_controls(scenario, a.scale, a.seed)
    print(
        f"episode: {Path(scenario).name}, the expert at {a.scale}x, seed {a.seed}: "
        f"{reference['sim_time_s']:.1f} s simulated, {len(controls)} control boundaries, "
        f"{frames} camera frames"
    )
    if abs(frames - len(controls)) > 1:  # the run's last tick can be a boundary without a frame
        print(
            f"warning: with the camera, mrdrive run renders {frames} frames and the environment "
            f"{len(controls)} observations: the camera rows compare unequal work",
            file=sys.stderr,
        )
    for camera in (True, False):
        what = f"camera rig at {a.scale}x" if camera else "no camera"
        rust_runs = [rust_rtf(scenario, a.scale, a.seed, camera) for _ in range(a.repeats)]
        env_runs = [env_replay(scenario, a.scale, a.seed, controls, camera) for _ in range(a.repeats)]
        for _, result in rust_runs:
            if diff := same_episode(reference, result):
                sys.exit(f"mrdrive run did not repeat the reference run: {diff}")
        for *_, result, _ in env_runs:
            if diff := same_episode(reference, result):
                sys.exit(f"the environment did not drive the expert's episode: {diff}")
        rust = statistics.median(r[0] for r in rust_runs)
        env_rtf = statistics.median(e[0] for e in env_runs)
        steps = statistics.median(e[1] for e in env_runs)
        print(
            f"{what}: mrdrive run {rust:.1f}x real time; Python env {env_rtf:.1f}x real time "
            f"({steps:.0f} steps/s); env / run = {env_rtf / rust:.2f}"
        )


if __name__ == "__main__":
    main()
