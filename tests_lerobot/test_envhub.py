"""EnvHub: LeRobot's own ``make_env`` loads ``envhub/env.py`` as a Hub environment.

The file is served from a local Hub cache (``HF_HUB_OFFLINE=1``, the layout
``huggingface_hub`` keeps for a downloaded repository), so LeRobot goes through its whole
hub path: parse the id, find ``env.py``, refuse without ``trust_remote_code``, import it,
call ``make_env`` and normalise the result.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")

from lerobot.envs.factory import make_env
from lerobot.envs.utils import preprocess_observation

ROOT = Path(__file__).resolve().parents[1]
REPO = "gym-soarm/so101-tabletop"
REVISION = "0" * 40


@pytest.fixture
def hub_cache(tmp_path, monkeypatch):
    """A Hub cache holding envhub/env.py as the repository's env.py at main."""
    import huggingface_hub.constants

    folder = tmp_path / f"models--{REPO.replace('/', '--')}"
    snapshot = folder / "snapshots" / REVISION
    snapshot.mkdir(parents=True)
    shutil.copy(ROOT / "envhub" / "env.py", snapshot / "env.py")
    (folder / "refs").mkdir()
    (folder / "refs" / "main").write_text(REVISION)
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_OFFLINE", True)
    return tmp_path


def test_lerobot_refuses_the_hub_env_without_trust(hub_cache):
    with pytest.raises(RuntimeError, match="trust_remote_code"):
        make_env(REPO, n_envs=1, hub_cache_dir=str(hub_cache))


def test_lerobot_loads_the_tabletop_contract_from_the_hub(hub_cache):
    envs = make_env(REPO, n_envs=2, hub_cache_dir=str(hub_cache), trust_remote_code=True)
    assert list(envs) == ["so101_tabletop"] and list(envs["so101_tabletop"]) == [0]
    vector = envs["so101_tabletop"][0]
    try:
        assert vector.num_envs == 2
        assert vector.metadata["render_fps"] == 30
        obs, _ = vector.reset(seed=[0, 1])
        assert obs["pixels"]["front"].shape == (2, 480, 640, 3)
        assert obs["pixels"]["wrist"].shape == (2, 480, 640, 3)
        batch = preprocess_observation(obs)  # what lerobot-eval feeds a policy
        assert batch["observation.images.front"].shape == (2, 3, 480, 640)
        assert batch["observation.images.wrist"].shape == (2, 3, 480, 640)
        assert batch["observation.state"].shape == (2, 6)
        # Holding the joints where they are (absolute targets in the follower's degrees):
        # no cube moves into the box.
        action = obs["agent_pos"].astype(np.float32)
        _, reward, _, _, info = vector.step(action)
        np.testing.assert_array_equal(reward, [0.0, 0.0])
        np.testing.assert_array_equal(info["cubes_in_box"], [0, 0])
        assert vector.call("task_description") == ("Put all the cubes in the green box.",) * 2
    finally:
        vector.close()
