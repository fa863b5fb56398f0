"""The ``soarm`` EnvConfig's ``vector_env``: gym_soarm's vector envs by one set of names.

``batched``, ``processes`` and ``warp`` are the names ``gym.make_vec``'s ``vector_env`` and
the trainer's ``--vector-env`` give gym_soarm's vector envs; the config takes them too,
beside Gymnasium's ``async`` and ``sync`` and ``auto``. Its earlier ``native`` still builds
what it built (batched with state observations, processes with cameras) and warns with
the name to use.

LeRobot needs Python >= 3.12, so where it is not installed the config module is read over
a stand-in of the few LeRobot names it imports (``EnvConfig``, ``FeatureType``,
``PolicyFeature``), loaded by its path so that nothing else sees the stand-in.
"""

from __future__ import annotations

import enum
import importlib.util
import sys
import types
import warnings
from dataclasses import dataclass

import numpy as np
import pytest
from paths import ROOT

from gym_soarm.vector import BatchedVectorEnv, SoArmVectorEnv

CONFIG_PATH = ROOT / "gym_soarm" / "lerobot" / "config.py"
STATE = {"obs_type": "environment_state_agent_pos", "task": "LiftCube-v0"}
PIXELS = {
    "obs_type": "pixels_agent_pos",
    "task": "LiftCube-v0",
    "camera_config": "front_only",
    "observation_height": 32,
    "observation_width": 32,
}


def _lerobot_stand_in() -> dict[str, types.ModuleType]:
    """The LeRobot modules the config imports, with just the names it uses."""

    class FeatureType(str, enum.Enum):
        STATE = "STATE"
        VISUAL = "VISUAL"
        ENV = "ENV"
        ACTION = "ACTION"

    @dataclass
    class PolicyFeature:
        type: FeatureType
        shape: tuple

    class EnvConfig:
        disable_env_checker = True

        @classmethod
        def register_subclass(cls, name):
            return lambda subclass: subclass

        def create_envs(self, n_envs, use_async_envs=False):  # LeRobot >= 0.6 asks for it
            raise NotImplementedError

    modules = {name: types.ModuleType(name) for name in ("lerobot", "lerobot.configs")}
    modules["lerobot.envs"] = types.ModuleType("lerobot.envs")
    modules["lerobot.configs.types"] = types.ModuleType("lerobot.configs.types")
    modules["lerobot.configs.types"].FeatureType = FeatureType
    modules["lerobot.configs.types"].PolicyFeature = PolicyFeature
    modules["lerobot.envs.configs"] = types.ModuleType("lerobot.envs.configs")
    modules["lerobot.envs.configs"].EnvConfig = EnvConfig
    return modules


@pytest.fixture(scope="module")
def config():
    """``gym_soarm.lerobot.config``: LeRobot's own, or the file over the stand-in."""
    if importlib.util.find_spec("lerobot") is not None:
        import gym_soarm.lerobot.config as module

        yield module
        return
    name = "_soarm_lerobot_config_under_test"
    added = {**_lerobot_stand_in(), name: None}
    saved = {key: sys.modules.get(key) for key in added}
    try:
        sys.modules.update({k: v for k, v in added.items() if v is not None})
        spec = importlib.util.spec_from_file_location(name, CONFIG_PATH)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        yield module
    finally:
        for key, value in saved.items():
            if value is None:
                sys.modules.pop(key, None)
            else:
                sys.modules[key] = value


def _make(config, **fields):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a new spelling builds without a warning
        return config.SoArmEnvConfig(**fields)


def test_the_vector_env_values_are_the_package_s_names(config):
    from gym_soarm.vector.batched import VECTOR_ENVS as ENV_VECTOR_ENVS

    assert config.PACKAGE_VECTOR_ENVS == ("batched", "processes", "warp")
    assert set(config.PACKAGE_VECTOR_ENVS) <= set(ENV_VECTOR_ENVS)
    for value in config.VECTOR_ENVS:
        assert _make(config, vector_env=value, **STATE).vector_env == value
    with pytest.raises(
        ValueError, match=r"vector_env must be one of 'auto', 'batched', 'processes', 'warp'"
    ):
        _make(config, vector_env="fast", **STATE)


@pytest.mark.parametrize(("fields", "new"), [(STATE, "batched"), (PIXELS, "processes")])
def test_native_warns_and_names_the_new_value(config, fields, new):
    with pytest.warns(
        FutureWarning, match=rf"vector_env='native' is deprecated; pass vector_env='{new}'"
    ):
        old = config.SoArmEnvConfig(vector_env="native", **fields)
    assert old.vector_env == "native"  # kept as given: LeRobot writes the config back
    (item,) = config.resolve_selection(old.task)
    assert old.package_vector_env(item) == new


def _rollout(vector, steps: int = 3) -> list:
    """Observations, rewards and ends of a short rollout from seed 7."""
    seen = []
    obs, _ = vector.reset(seed=7)
    seen.append(obs)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        action = rng.uniform(-0.2, 0.2, vector.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, _ = vector.step(action)
        seen.append((obs, reward, terminated, truncated))
    return seen


def _same(a, b) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            _same(a[key], b[key])
    elif isinstance(a, (tuple, list)):
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    else:
        np.testing.assert_array_equal(a, b)


def _envs(config, vector_env: str, fields: dict, n_envs: int = 2):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        made = config.SoArmEnvConfig(vector_env=vector_env, **fields)
    (group,) = made.create_envs(n_envs).values()
    return group[0]


@pytest.mark.parametrize(
    ("fields", "new", "kind"),
    [(STATE, "batched", BatchedVectorEnv), (PIXELS, "processes", SoArmVectorEnv)],
)
def test_native_and_its_new_name_build_the_same_env(config, fields, new, kind):
    rollouts = []
    for value in ("native", new, "auto"):
        vector = _envs(config, value, fields)
        try:
            assert isinstance(vector, kind), (value, type(vector))
            rollouts.append(_rollout(vector))
        finally:
            vector.close()
    _same(rollouts[0], rollouts[1])
    _same(rollouts[0], rollouts[2])


def test_one_environment_of_a_package_vector_env_is_that_env(config):
    vector = _envs(config, "batched", STATE, n_envs=1)
    try:
        assert isinstance(vector, BatchedVectorEnv) and vector.num_envs == 1
    finally:
        vector.close()
    vector = _envs(config, "auto", STATE, n_envs=1)  # auto keeps one env in a SyncVectorEnv
    try:
        assert type(vector).__name__ == "SyncVectorEnv"
    finally:
        vector.close()
