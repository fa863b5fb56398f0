"""The vector envs' shell is written once (gym_soarm.vector.base.SoArmVectorBase); the
batched and process envs only move actions, observations and calls."""

from __future__ import annotations

import pytest

from gym_soarm.vector import BatchedVectorEnv, SoArmVectorEnv
from gym_soarm.vector.base import SoArmVectorBase

SHELL = (
    "reset",
    "step",
    "call",
    "call_some",
    "get_attr",
    "set_attr",
    "render",
    "close",
    "_check_open",
    "_note_ends",
    "_add_finals",
    "_batched_obs",
)
TRANSPORT = ("_reset", "_step", "_call", "_get_attr", "_set_attr", "close_extras")


@pytest.mark.parametrize("vector_env", [BatchedVectorEnv, SoArmVectorEnv], ids=lambda c: c.__name__)
def test_every_vector_env_is_transport_over_the_base(vector_env):
    assert issubclass(vector_env, SoArmVectorBase)
    for name in SHELL:
        assert name not in vars(vector_env), f"{vector_env.__name__} redefines {name}()"
    for name in TRANSPORT:
        assert name in vars(vector_env), f"{vector_env.__name__} lacks {name}()"
