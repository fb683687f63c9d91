"""The Gymnasium environment against a real `mrdrive serve` (numpy and gymnasium only).

Run from the repository root after `cargo build --release`:
    python -m unittest discover -s python/tests -v
(`cargo xtask test` runs it through tests/python_env.rs, with MRDRIVE_BIN set.)
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import unittest
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import mrdrive_gym  # noqa: E402
from mrdrive_gym import MrdriveEnv, ServerError  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT / "scenarios" / "default.toml"


def scripted(k: int) -> list[float]:
    """The scripted driver of the Rust cross-check (tests/python_env.rs): step k's control.
    Values are exact in binary so both sides hand the loop the same f32s."""
    steer = ((k % 7) - 3) / 32.0
    throttle = 0.5 if (k // 20) % 3 != 2 else 0.0
    brake = 0.0 if throttle > 0 else 0.25
    return [steer, throttle, brake]


class EnvTest(unittest.TestCase):
    def make(self, **kw) -> MrdriveEnv:
        env = MrdriveEnv(DEFAULT, **kw)
        self.addCleanup(env.close)
        return env

    def test_gymnasium_env_checker_passes(self):
        env = self.make(scale=0.75)
        check_env(env, skip_render_check=True)

    def test_the_class_image_and_the_privileged_state_are_options(self):
        env = self.make(scale=0.75, classes=True, privileged=True)
        check_env(env, skip_render_check=True)
        obs, _ = env.reset(seed=3)
        for _ in range(10):
            obs, *_ = env.step(np.array([0.0, 0.5, 0.0], np.float32))
        c = obs["classes"]
        self.assertEqual(c.shape, obs["image"].shape[:2])
        self.assertTrue((c == 1).mean() > 0.05, "road is in view")
        self.assertTrue(c.max() <= 5)
        self.assertGreater(float(obs["route_s"][0]), 0.0)
        self.assertEqual(obs["ego_pose"].shape, (3,))

    def test_an_episode_records_an_mcap_log(self):
        with tempfile.TemporaryDirectory() as d:
            log = Path(d) / "episode.mcap"
            env = self.make(scale=1.0, vehicles=0, pedestrians=0, record=log)
            env.reset(seed=0)
            done = False
            while not done:  # held brake: the 40 s low-speed timeout ends it
                _, _, term, trunc, info = env.step(np.array([0.0, 0.0, 1.0], np.float32))
                done = term or trunc
            self.assertEqual(info["record"]["result"]["termination"], "low_speed_timeout")
            data = log.read_bytes()
            self.assertTrue(data.startswith(b"\x89MCAP0\r\n") and data.endswith(b"\x89MCAP0\r\n"))
            self.assertGreater(len(data), 10_000)

    def test_make_registers_the_id(self):
        env = gym.make(mrdrive_gym.ENV_ID, scenario=str(DEFAULT), scale=0.75, vehicles=0, pedestrians=0)
        self.addCleanup(env.close)
        obs, _ = env.reset(seed=0)
        self.assertEqual(obs["image"].shape, env.observation_space["image"].shape)

    def test_the_same_seed_gives_the_same_episode(self):
        env = self.make(scale=0.75)

        def episode(seed):
            obs, _ = env.reset(seed=seed)
            images, rewards = [obs["image"].copy()], []
            for k in range(40):
                obs, r, term, trunc, _ = env.step(np.array(scripted(k), np.float32))
                rewards.append(r)
                if term or trunc:
                    break
                images.append(obs["image"].copy())
            return images, rewards

        a, b = episode(4), episode(4)
        self.assertEqual(len(a[0]), len(b[0]))
        for x, y in zip(a[0], b[0]):
            np.testing.assert_array_equal(x, y)
        self.assertEqual(a[1], b[1])

    def test_discrete_actions_and_a_scale_chosen_by_the_agent(self):
        env = self.make(actions="discrete", agent_scales=(0.75, 1.0), vehicles=0, pedestrians=0)
        obs, _ = env.reset(seed=1)
        self.assertEqual(tuple(obs["image_hw"]), env.observation_space["image"].shape[:2])
        obs, *_ = env.step({"control": 27, "scale": 0})
        h, w = obs["image_hw"]
        self.assertLess(h, env.observation_space["image"].shape[0])
        self.assertAlmostEqual(float(obs["scale"][0]), 0.75, places=5)
        self.assertFalse(obs["image"][h:].any(), "the padding stays black")
        with self.assertRaises(ValueError):
            env.step({"control": 28, "scale": 0})
        with self.assertRaises(ValueError):
            env.step({"control": 3, "scale": 2})

    def test_bad_input_names_what_was_wrong(self):
        with self.assertRaises(FileNotFoundError):
            MrdriveEnv(ROOT / "scenarios" / "no-such.toml")
        with tempfile.TemporaryDirectory() as d:
            bad = Path(d) / "bad.toml"
            bad.write_text('[map]\nfile = "x.xodr"\n[route]\nfile = "r.toml"\nid = 0\n[timing]\ndelay_ms = -5\n')
            with self.assertRaises(ServerError) as e:
                MrdriveEnv(bad)
            self.assertIn("delay_ms", str(e.exception))
        env = self.make(scale=0.75)
        env.reset(seed=0)
        for action in ([0.0, 2.0, 0.0], [0.0, 0.5], [[0.0, 0.5, 0.0]], [np.nan, 0.0, 0.0]):
            with self.assertRaises(ValueError, msg=str(action)):
                env.step(np.array(action, np.float32))
        # The server itself refuses out-of-range controls that bypass the checks.
        with self.assertRaises(ServerError) as e:
            env._server.request({"op": "step", "control": [0.0, 1.5, 0.0]})
        self.assertIn("out of range", str(e.exception))

    def test_a_dead_server_is_an_exception_and_close_leaves_no_process(self):
        env = self.make(scale=0.75)
        env.reset(seed=0)
        proc = env._server.proc
        proc.kill()
        proc.wait()
        with self.assertRaises(ServerError) as e:
            env.step(np.array([0.0, 0.5, 0.0], np.float32))
        self.assertIn("exited", str(e.exception))
        env2 = self.make(scale=0.75)
        env2.reset(seed=0)
        p2 = env2._server.proc
        env2.close()
        self.assertIsNotNone(p2.poll(), "close ends the server")

    def test_ten_environments_in_one_process(self):
        envs = gym.vector.SyncVectorEnv(
            [lambda: MrdriveEnv(DEFAULT, scale=0.75, vehicles=2, pedestrians=2) for _ in range(10)]
        )
        self.addCleanup(envs.close)
        obs, _ = envs.reset(seed=list(range(10)))
        self.assertEqual(obs["image"].shape[0], 10)
        for _ in range(5):
            obs, r, term, trunc, _ = envs.step(np.tile(np.array([0.0, 0.5, 0.0], np.float32), (10, 1)))
        self.assertEqual(r.shape, (10,))

    def test_scripted_driver_record(self):
        """Drives the scripted controls to the end; tests/python_env.rs drives the same
        controls in Rust and compares the result records (the path comes from there)."""
        env = self.make(scale=0.75)
        env.reset(seed=2)
        total, k = 0.0, 0
        while True:
            _, r, term, trunc, info = env.step(np.array(scripted(k), np.float32))
            total += r
            k += 1
            if term or trunc:
                break
        record = info["record"]
        result = record["result"]
        # The rewards sum to the completion minus each infraction's cost (sim/src/remote.rs).
        cost = {"collision_pedestrian": 50, "collision_vehicle": 40, "collision_static": 35, "red_light": 30}
        expected = result["completion_pct"] - sum(cost.get(i["kind"], 0) for i in result["infractions"])
        self.assertAlmostEqual(total, expected, places=6)
        out = os.environ.get("MRDRIVE_SCRIPTED_RECORD")
        if out:
            Path(out).write_text(json.dumps({"steps": k, "record": record}))


def have_mcap() -> bool:
    try:
        import mcap.reader  # noqa: F401
    except ImportError:
        return False
    return True


class SpeedBenchTest(unittest.TestCase):
    @unittest.skipUnless(have_mcap(), "the mcap package is missing (cargo xtask setup installs it)")
    def test_the_speed_bench_drives_one_episode_on_both_sides(self):
        """bench/env_speed.py compares `mrdrive run --expert` with the environment replaying
        that expert's controls: the two must be one episode, tick for tick."""
        import importlib.util

        spec = importlib.util.spec_from_file_location("env_speed", ROOT / "bench" / "env_speed.py")
        bench = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(bench)
        scenario = str(DEFAULT.resolve())
        controls, reference, frames = bench.expert_controls(scenario, 0.75, 1)
        self.assertGreater(len(controls), 100)
        self.assertLessEqual(abs(frames - len(controls)), 1, "the camera rows compare equal work at 0.75x")
        *_, result, steps = bench.env_replay(scenario, 0.75, 1, controls, camera=False)
        self.assertEqual(steps, len(controls))
        self.assertEqual(bench.same_episode(reference, result), {})
        _, rust = bench.rust_rtf(scenario, 0.75, 1, camera=False)
        self.assertEqual(bench.same_episode(reference, rust), {})


if __name__ == "__main__":
    unittest.main()
