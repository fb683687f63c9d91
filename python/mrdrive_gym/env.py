"""`mrdrive/Scenario-v0`: one mrdrive scenario as a Gymnasium environment.

One `step` is one control period of mrdrive's synchronous loop: the control
goes through the same delay line and zero-order hold as mrdrive's own
drivers' (docs/protocol.md §1), and the next observation comes at the next control
boundary. The simulator runs in a `mrdrive serve` process per environment.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .client import Server, ServerError, classes_of, image_of

#: Route commands (CARLA's RoadOption - 1), the values of `obs["command"]`.
COMMANDS = ("LEFT", "RIGHT", "STRAIGHT", "LANEFOLLOW", "CHANGELANELEFT", "CHANGELANERIGHT")
#: WoR's 28 discrete actions: index j < 27 is steer STEERS[j % 9] with throttle
#: THROTTLES[j // 9]; 27 is full brake (the server maps them: dataset/src/action.rs).
STEERS = tuple(np.linspace(-1.0, 1.0, 9).tolist())
THROTTLES = (0.0, 0.5, 1.0)
NUM_ACTIONS = 28


class MrdriveEnv(gym.Env):
    """A scenario file of mrdrive, driven from Python.

    Args:
        scenario: a scenario TOML file (the same files and overrides as `mrdrive run`).
        delay_ms, vehicles, pedestrians: overrides of the scenario's delay D and traffic.
        scale: a fixed input scale (fraction of S0); None keeps the scenario's selector.
        agent_scales: the scales the agent may choose from (e.g. (0.75, 1.0)); the
            action then holds the scale of the next observation.
        actions: "continuous" (steer in [-1, 1], throttle and brake in [0, 1]) or
            "discrete" (WoR's 28 actions).
        record: an MCAP file to record each episode to (overwritten at each reset).
        binary: the mrdrive executable (default: $MRDRIVE_BIN, the repository's build, PATH).
        camera: False renders nothing: "image" stays black (for agents that do not
            look, and for timing the simulator without its camera).
        classes: add "classes", the rig's class image (WoR's 6 ids: background, road,
            lane marking, vehicle, pedestrian, traffic light), uint8 H x W.
        privileged: add "ego_pose" (x, y in metres, heading in radians), "route_s"
            (metres along the route) and "completion" (percent): exact state, for
            privileged agents and reward shaping.

    Observation (a dict): "image" (uint8 H x W x 3, the stitched rig image at the
    scale in force; when the scale can change, it is placed top-left in an S0-sized
    array and "image_hw" gives its size), "speed" (m/s), "command" (see COMMANDS),
    "time" (s), "scale", "image_hw".

    Reward: route completion gained (percentage points) minus, per infraction, what
    it costs leaderboard-1.0's driving score: pedestrian 50, vehicle 40, static 35,
    red light 30 (src/sim/remote.rs). A clean, complete episode sums to 100.

    `info` holds the step's "infractions", "completion_pct", "route_s" and "ego_pose";
    at the end also "record", the result record of `mrdrive run --json`.
    An episode ends by the scenario's own rules: `terminated` on success or an
    ending infraction, `truncated` on the route timeout.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        scenario: str | os.PathLike,
        *,
        delay_ms: float | None = None,
        vehicles: int | None = None,
        pedestrians: int | None = None,
        scale: float | None = None,
        agent_scales: Sequence[float] | None = None,
        actions: str = "continuous",
        record: str | os.PathLike | None = None,
        binary: str | os.PathLike | None = None,
        render_mode: str | None = None,
        camera: bool = True,
        classes: bool = False,
        privileged: bool = False,
    ):
        if actions not in ("continuous", "discrete"):
            raise ValueError(f"actions={actions!r}: use 'continuous' or 'discrete'")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: only 'rgb_array' is supported")
        path = Path(scenario).expanduser().resolve()
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such scenario file")
        self.scenario = str(path)
        self.overrides = {"delay_ms": delay_ms, "vehicles": vehicles, "pedestrians": pedestrians}
        self.agent_scales = tuple(float(s) for s in agent_scales) if agent_scales else None
        self.fixed_scale = None if self.agent_scales else scale
        self.first_scale = scale if scale is not None else (self.agent_scales[-1] if self.agent_scales else None)
        self.actions = actions
        self.record = str(Path(record).resolve()) if record else None
        self.render_mode = render_mode
        self.camera = bool(camera)
        self.classes = bool(classes) and self.camera
        self.privileged = bool(privileged)
        self._server = Server(binary)
        scales = list(self.agent_scales or ([scale] if scale is not None else []))
        spec, _ = self._server.request({"op": "spec", "scenario": self.scenario, "scales": scales})
        h0, w0 = spec["s0"]
        if self.fixed_scale is not None:
            h, w = spec["sizes"][0]
        else:
            h, w = h0, w0
        self._image_shape = (h, w, 3)
        extra = {}
        if self.classes:
            extra["classes"] = spaces.Box(0, 5, self._image_shape[:2], np.uint8)
        if self.privileged:
            extra["ego_pose"] = spaces.Box(-1e6, 1e6, (3,), np.float32)
            extra["route_s"] = spaces.Box(0.0, 1e6, (1,), np.float32)
            extra["completion"] = spaces.Box(0.0, 100.0, (1,), np.float32)
        self.observation_space = spaces.Dict(
            {
                **extra,
                "image": spaces.Box(0, 255, self._image_shape, np.uint8),
                "image_hw": spaces.Box(0, max(h, w), (2,), np.int64),
                "speed": spaces.Box(0.0, 100.0, (1,), np.float32),
                "command": spaces.Discrete(len(COMMANDS)),
                "time": spaces.Box(0.0, 1e6, (1,), np.float32),
                "scale": spaces.Box(0.0, 1.0, (1,), np.float32),
            }
        )
        control = (
            spaces.Discrete(NUM_ACTIONS)
            if actions == "discrete"
            else spaces.Box(np.array([-1, 0, 0], np.float32), np.array([1, 1, 1], np.float32), dtype=np.float32)
        )
        if self.agent_scales:
            self.action_space = spaces.Dict({"control": control, "scale": spaces.Discrete(len(self.agent_scales))})
        else:
            self.action_space = control
        self._last_image = np.zeros(self._image_shape, np.uint8)
        self._last_obs: dict[str, Any] | None = None
        self._running = False

    def _observation(self, obs: dict[str, Any], payload: bytes, info: dict[str, Any]) -> dict[str, Any]:
        img = image_of(obs, payload)
        h, w = img.shape[:2]
        if img.shape == self._image_shape:
            image = img.copy()
        else:
            image = np.zeros(self._image_shape, np.uint8)
            image[:h, :w] = img
        self._last_image = image
        extra = {}
        if self.classes:
            classes = np.zeros(self._image_shape[:2], np.uint8)
            c = classes_of(obs, payload)
            classes[: c.shape[0], : c.shape[1]] = c
            extra["classes"] = classes
        if self.privileged:
            extra["ego_pose"] = np.array(info["ego_pose"], np.float32)
            extra["route_s"] = np.array([info["route_s"]], np.float32)
            extra["completion"] = np.array([min(max(info["completion_pct"], 0.0), 100.0)], np.float32)
        return {
            **extra,
            "image": image,
            "image_hw": np.array([h, w], np.int64),
            "speed": np.array([obs["speed_mps"]], np.float32),
            "command": int(obs["command"]),
            "time": np.array([obs["time_s"]], np.float32),
            "scale": np.array([obs["scale"]], np.float32),
        }

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        message = {
            "op": "reset",
            "scenario": self.scenario,
            "seed": seed,
            "scale": self.first_scale,
            "agent_scale": bool(self.agent_scales),
            "record": self.record,
            "camera": self.camera,
            "classes": self.classes,
            **self.overrides,
        }
        answer, payload = self._server.request(message)
        if answer["done"]:
            raise ServerError("the episode ended before its first control boundary")
        self._running = True
        self._last_obs = self._observation(answer["obs"], payload, answer["info"])
        return self._last_obs, answer["info"]

    def _control(self, action) -> dict[str, Any]:
        if self.agent_scales:
            if not isinstance(action, dict) or set(action) != {"control", "scale"}:
                raise ValueError("the action must be a dict {'control': ..., 'scale': index into agent_scales}")
            k = int(action["scale"])
            if not 0 <= k < len(self.agent_scales):
                raise ValueError(f"scale index {k} out of range 0..{len(self.agent_scales) - 1}")
            out = self._control_only(action["control"])
            out["scale"] = self.agent_scales[k]
            return out
        return self._control_only(action)

    def _control_only(self, control) -> dict[str, Any]:
        if self.actions == "discrete":
            j = int(np.asarray(control).reshape(()))
            if not 0 <= j < NUM_ACTIONS:
                raise ValueError(f"action {j} out of range 0..{NUM_ACTIONS - 1}")
            return {"action": j}
        c = np.asarray(control, np.float64)
        if c.shape != (3,):
            raise ValueError(f"the control must have shape (3,) [steer, throttle, brake], got {c.shape}")
        if not np.all(np.isfinite(c)):
            raise ValueError(f"the control {c.tolist()} holds a NaN or infinity")
        lo, hi = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 1.0, 1.0])
        if np.any(c < lo - 1e-6) or np.any(c > hi + 1e-6):
            raise ValueError(
                f"the control {c.tolist()} is out of range: steer in [-1, 1], throttle and brake in [0, 1]"
            )
        # float32 rounding may step a hair outside; the server checks the exact range.
        return {"control": np.clip(c, lo, hi).tolist()}

    def step(self, action):
        if not self._running:
            raise RuntimeError("call reset() before step() (the episode has ended or not begun)")
        answer, payload = self._server.request({"op": "step", **self._control(action)})
        info = answer["info"]
        if answer["done"]:
            self._running = False
            record = info["record"]["result"]
            truncated = record.get("termination") == "route_timeout"
            return self._last_obs, float(answer["reward"]), not truncated, truncated, info
        self._last_obs = self._observation(answer["obs"], payload, info)
        return self._last_obs, float(answer["reward"]), False, False, info

    def render(self):
        if self.render_mode == "rgb_array":
            return self._last_image
        return None

    def close(self):
        self._running = False
        if getattr(self, "_server", None) is not None:
            self._server.close()
            self._server = None
