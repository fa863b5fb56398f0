"""The kernel cache for ``vector_env="warp"`` on a GPU, built here without one: a task's
scene stepped on Warp's CPU device, a module compiled for sm_90 into the folder (a real
CUDA binary, read back), the manifest, and bad input refused before anything is built."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from gym_soarm.sim.warp_backend import warp_available
from gym_soarm.sim.warp_cache import MANIFEST, check_archs

if not warp_available():
    if os.environ.get("GYM_SOARM_REQUIRE_WARP") == "1":
        raise ImportError("GYM_SOARM_REQUIRE_WARP=1 but MuJoCo Warp is not installed.")
    pytest.skip('MuJoCo Warp: pip install "gym-soarm[warp]"', allow_module_level=True)


def _program(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "gym_soarm.kernels", *args],
        capture_output=True,
        text=True,
        timeout=1500,
    )


@pytest.mark.subprocess
@pytest.mark.slow
def test_cache_holds_cuda_binaries_for_the_named_architecture(tmp_path):
    out = tmp_path / "kcache"
    run = _program("--out", str(out), "--arch", "90", "--task", "reach", "--limit", "2")
    assert run.returncode == 0, run.stderr
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["arch"] == [90] and manifest["tasks"] == ["ReachTarget-v0"]
    assert len(manifest["compiled"]) + len(manifest["skipped"]) == 2
    assert manifest["compiled"], manifest
    cubins = sorted(out.rglob("*.sm90.cubin")) or sorted(out.rglob("*sm90*"))
    assert cubins, sorted(p.name for p in out.rglob("*"))[:20]
    # A CUDA binary: an ELF file (a cubin), not a placeholder.
    assert cubins[0].read_bytes()[:4] == b"\x7fELF"
    # The CPU build's objects are gone unless --keep-cpu.
    assert not [p for p in out.rglob("*") if p.suffix in (".o", ".cpp")]
    assert json.loads(run.stdout.strip().splitlines()[-1])["compiled"] == len(manifest["compiled"])


@pytest.mark.parametrize("arch", [0, 9, "90", [90, True], []])
def test_bad_architectures_are_refused(arch):
    with pytest.raises(ValueError, match="CUDA architectures as ints"):
        check_archs(arch)


@pytest.mark.subprocess
def test_program_refuses_bad_input_before_building(tmp_path):
    run = _program("--out", str(tmp_path / "k"), "--arch", "7")
    assert run.returncode == 2 and "CUDA architectures as ints" in run.stderr
    run = _program("--out", str(tmp_path / "k"), "--task", "juggle")
    assert run.returncode == 2 and "juggle" in run.stderr
    assert not (tmp_path / "k").exists()
