"""Gymnasium environments backed by mrdrive: `import mrdrive_gym`, then
`gymnasium.make("mrdrive/Scenario-v0", scenario="scenarios/default.toml")`."""

from __future__ import annotations

import gymnasium

from .client import Server, ServerError
from .env import COMMANDS, NUM_ACTIONS, MrdriveEnv

ENV_ID = "mrdrive/Scenario-v0"


def register_envs() -> None:
    """Registers `mrdrive/Scenario-v0` (idempotent; also Gymnasium's entry point)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point="mrdrive_gym.env:MrdriveEnv", disable_env_checker=True)


register_envs()

__all__ = ["COMMANDS", "ENV_ID", "MrdriveEnv", "NUM_ACTIONS", "Server", "ServerError", "register_envs"]
