"""The Python environment's speed next to `mrdrive run`'s, on the same scenario.

    python bench/env_speed.py [--scenario scenarios/default.toml] [--repeats 3]

`mrdrive run` drives the expert; the environment is driven from Python with a
held brake (the ego stands, traffic goes on) until the scenario ends it (the
40 s low-speed timeout). Each prints simulated seconds per wall second (the
real-time factor) with the camera rig at 1.0x and without a camera, medians of
`--repeats` runs. Needs numpy and gymnasium, and a release build.
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

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from mrdrive_gym import MrdriveEnv  # noqa: E402
from mrdrive_gym.client import find_binary  # noqa: E402


def rust_rtf(scenario: str, camera: bool) -> float:
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "run.json"
        cmd = [find_binary(), "run", scenario, "--scale", "1.0", "--quiet", "--json", str(out)]
        if camera:
            cmd.append("--camera")
        subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return json.loads(out.read_text())["perf"]["real_time_factor"]


def env_rtf(scenario: str, camera: bool) -> tuple[float, float]:
    env = MrdriveEnv(scenario, scale=1.0, camera=camera)
    try:
        t0 = time.perf_counter()
        env.reset(seed=0)
        steps, done = 0, False
        brake = np.array([0.0, 0.0, 1.0], np.float32)
        while not done:
            _, _, term, trunc, info = env.step(brake)
            steps += 1
            done = term or trunc
        wall = time.perf_counter() - t0
        sim_s = info["record"]["result"]["sim_time_s"]
        return sim_s / wall, steps / wall
    finally:
        env.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="scenarios/default.toml")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    scenario = str((ROOT / a.scenario).resolve())
    for camera in (True, False):
        what = "camera rig at 1.0x" if camera else "no camera"
        rust = statistics.median(rust_rtf(scenario, camera) for _ in range(a.repeats))
        env = [env_rtf(scenario, camera) for _ in range(a.repeats)]
        env_rtf_med = statistics.median(e[0] for e in env)
        steps = statistics.median(e[1] for e in env)
        print(
            f"{what}: mrdrive run {rust:.1f}x real time; Python env {env_rtf_med:.1f}x real time "
            f"({steps:.0f} steps/s); env / run = {env_rtf_med / rust:.2f}"
        )


if __name__ == "__main__":
    main()
