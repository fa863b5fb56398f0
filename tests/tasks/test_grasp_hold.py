"""The grasp benchmark: friction-only lift-and-carry of three shapes (SPEC section 28)."""

from __future__ import annotations

import json

import pytest

from gym_soarm.bench import grasp_hold
from gym_soarm.cli import grasp_hold as grasp_hold_cli


def test_a_lift_and_carry_of_each_shape_is_measured(tmp_path):
    out = tmp_path / "hold.json"
    grasp_hold_cli.main(["--episodes", "3", "--seed", "0", "--json", str(out)])
    report = json.loads(out.read_text())
    rows = report["rows"]
    assert [r["shape"] for r in rows] == ["cube", "cylinder", "block"]
    assert [r["seed"] for r in rows] == [0, 1, 2]
    for row in rows:
        low, high = grasp_hold.MASS_RANGE_KG
        assert low <= row["mass_kg"] <= high
        if row["lifted"]:
            assert isinstance(row["held"], bool) and row["slip_mm"] >= 0.0
        else:
            assert row["held"] is None and row["slip_mm"] is None
    summary = report["all"]
    lifted = [r for r in rows if r["lifted"]]
    assert summary["lifted"] == len(lifted) and summary["episodes"] == 3
    assert summary["held"] == sum(r["held"] for r in lifted)
    assert set(report["shapes"]) == {"cube", "cylinder", "block"}


def test_the_mass_is_set_on_the_object():
    import gymnasium as gym

    (cube, *_) = grasp_hold.shapes()
    env = gym.make(f"gym_soarm/{cube.task}", obs_type="state")
    env.reset(seed=0)
    physics = env.unwrapped.physics
    body = physics.model.name2id(cube.obj, "body")
    before = physics.model.ptr.body_inertia[body].copy()
    mass = float(physics.model.ptr.body_mass[body])
    grasp_hold._set_mass(env, cube.obj, 2 * mass)
    assert physics.model.ptr.body_mass[body] == pytest.approx(2 * mass)
    assert physics.model.ptr.body_inertia[body] == pytest.approx(2 * before)
    env.close()


def test_bad_episode_counts_are_refused(capsys):
    with pytest.raises(SystemExit):
        grasp_hold_cli.main(["--episodes", "0"])
    assert "--episodes must be >= 1" in capsys.readouterr().err
