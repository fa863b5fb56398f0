#!/usr/bin/env bash
# The pixel baselines of docs/learning.md (SPEC section 25), on this machine: a student
# that sees the front and wrist cameras (96 x 128) and agent_pos, taught by the task's
# state expert (ALGO=bc or dagger, the default), three training seeds a task, each
# policy then scored on the benchmark's protocol (50 episodes, seeds 1000 + k).
#   scripts/pixel_baselines.sh [OUT] [TASK ...]
# Each run's folder (model, settings, curve) lands in OUT/<task>/seed<k>, its protocol
# score in OUT/<task>/seed<k>/protocol.json. Extra train flags: TRAIN_FLAGS="--device
# cuda" (a GPU), TRAIN_FLAGS="--visual-randomization light" (the robust variant). Then
#   python scripts/summarize_rl.py OUT --json docs/pixel_baselines.json
set -euo pipefail
OUT="${1:-runs/pixels}"
shift || true
TASKS=("$@")
if [ ${#TASKS[@]} -eq 0 ]; then
    TASKS=(ReachTarget-v0 LiftCube-v0 PushCube-v0 PickAndPlaceCube-v0)
fi
ALGO="${ALGO:-dagger}"
SEEDS="${SEEDS:-0 1 2}"
TRAIN_FLAGS="${TRAIN_FLAGS:-}"
export MUJOCO_GL="${MUJOCO_GL:-egl}"

for seed in $SEEDS; do
    for task in "${TASKS[@]}"; do
        dir="$OUT/$task/seed$seed"
        if [ -f "$dir/protocol.json" ]; then continue; fi
        # shellcheck disable=SC2086
        python -m gym_soarm.train --algo "$ALGO" --task "$task" --seed "$seed" --out "$dir" \
            --obs-type pixels_agent_pos --camera-config front_wrist \
            --observation-height 96 --observation-width 128 $TRAIN_FLAGS
        python -m gym_soarm.evaluate --policy "$dir" --episodes 50 --json "$dir/protocol.json"
    done
done
