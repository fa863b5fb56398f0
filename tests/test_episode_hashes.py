"""Same seeds, same episodes, bit for bit: every task against hashes recorded earlier.

For every registered task, with ``obs_type="environment_state_agent_pos"``: the scripted
expert's episodes on seeds 0 and 1 (to their end) and 50 steps of seeded random actions
from seed 2. Every observation, reward, terminated and truncated flag, and the info's
``is_success``, ``reward_terms`` and the task's own keys are hashed (sha256) and compared
with the hashes recorded before the task contract was restructured (SPEC section 19).

A change that is meant to change episodes (new physics, new rewards) re-records them:
``python -c "from tests.test_episode_hashes import record; record()"`` prints the table.
"""

from __future__ import annotations

import hashlib
import struct
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import gym_soarm
from gym_soarm.expert import make_expert

EXPERT_SEEDS = (0, 1)
RANDOM_SEED = 2
RANDOM_STEPS = 50

RECORDED = {
    "PickAndPlaceCube-v0": "1d4831d78efe9460997d48d717eee4a7f6befddddd5bd582abe790241bbb1655",
    "LiftCube-v0": "1fd0d6fa7d685f7a2c5a8f87247e9d3f48d5097687d8b929e460d8152f763df3",
    "ReachTarget-v0": "5bd03256cdcdea41422988f41adc797052d5a3efaae89402f45e280f2bd2d6dd",
    "PushCube-v0": "052c01fffceb752aeaf2f13e764b1536b88cb9ca9307d11ef4fbee3ecf89a554",
    "StackCube-v0": "e71d1a033ec3717210e8b3d3bf2ebd373a16e993c96890b0f756bc7f4de8c382",
    "PlaceInBin-v0": "85acb36f45ef7dad6f0f726ca9d195165a0a40e4a177ae1fa832fa1f4c4ded1d",
    "PickAndPlaceCylinder-v0": "ff56fe0622f9c9dcb910166eee388c44d229859c17cfbd45602d87fe26c56a05",
    "OpenDrawer-v0": "a3c77ef13254cccd28eae8461a890b82ea30fa68cafeacfe0f8b8a16b84877d4",
    "PickColoredCube-v0": "69106d00830aa3bd9014554658097e63e820cccd67ffd7552726aa32e5cce931",
    "SortCubes-v0": "8dcf7968cc517deb2d703f12787a2f2afdabae195de70877be7654dfa747b6d8",
}


def _feed(digest: Any, value: Any) -> None:
    """Feed ``value`` into ``digest`` canonically: type, shape and the exact bytes."""
    if isinstance(value, np.ndarray):
        digest.update(f"a{value.dtype.str}{value.shape}".encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, dict):
        digest.update(b"{")
        for key in sorted(value):
            digest.update(repr(key).encode())
            _feed(digest, value[key])
        digest.update(b"}")
    elif isinstance(value, list | tuple):
        digest.update(b"[")
        for item in value:
            _feed(digest, item)
        digest.update(b"]")
    elif isinstance(value, bool | np.bool_):
        digest.update(b"T" if value else b"F")
    elif isinstance(value, float | np.floating):
        digest.update(b"f" + struct.pack("<d", float(value)))
    elif isinstance(value, int | np.integer):
        digest.update(b"i" + repr(int(value)).encode())
    elif isinstance(value, str) or value is None:
        digest.update(b"s" + repr(value).encode())
    else:
        raise TypeError(f"cannot hash {type(value).__name__} {value!r}; add it to _feed")


def _info_part(info: dict[str, Any], task_keys: set[str]) -> dict[str, Any]:
    keys = {"is_success", "reward_terms"} | task_keys
    return {key: info[key] for key in keys}


def episode_hashes(task: str) -> str:
    """The sha256 of the task's expert episodes and seeded random steps."""
    env = gym.make(gym_soarm.get_task(task).env_id, obs_type="environment_state_agent_pos")
    digest = hashlib.sha256()
    try:
        base = env.unwrapped
        expert = make_expert(env)
        for seed in EXPERT_SEEDS:
            obs, info = env.reset(seed=seed)
            task_keys = set(base.task_logic.episode_info(base.physics))
            expert.reset()
            _feed(digest, (obs, _info_part(info, task_keys)))
            while True:
                obs, reward, terminated, truncated, info = env.step(expert(obs, info))
                _feed(digest, (obs, reward, terminated, truncated, _info_part(info, task_keys)))
                if terminated or truncated:
                    break
        obs, info = env.reset(seed=RANDOM_SEED)
        env.action_space.seed(RANDOM_SEED)
        _feed(digest, (obs, _info_part(info, task_keys)))
        for _ in range(RANDOM_STEPS):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            _feed(digest, (obs, reward, terminated, truncated, _info_part(info, task_keys)))
            if terminated or truncated:
                break
    finally:
        env.close()
    return digest.hexdigest()


def record() -> None:
    """Print the ``RECORDED`` table of the current code (to re-record on purpose)."""
    for task in gym_soarm.task_names():
        print(f'    "{task}": "{episode_hashes(task)}",')


@pytest.mark.parametrize("task", gym_soarm.task_names())
def test_same_seeds_give_the_recorded_episodes(task):
    assert task in RECORDED, f"no recorded hash for {task}: record() prints the table"
    assert episode_hashes(task) == RECORDED[task], (
        f"{task}: the episodes of seeds {EXPERT_SEEDS} and the random steps of seed "
        f"{RANDOM_SEED} changed. If the change is meant, re-record with record()."
    )
