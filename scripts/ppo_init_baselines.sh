#!/usr/bin/env bash
# PPO started from the seed-0 behaviour-cloning policies of scripts/imitation_baselines.sh
# (docs/learning.md, "Baselines on two CPU cores"): one training seed per task, 200k steps,
# each policy then scored on the benchmark's protocol (50 episodes, seeds 1000 + k).
#   scripts/ppo_init_baselines.sh [IMITATION_OUT] [OUT] [TASK ...]
set -euo pipefail
FROM="${1:-runs/imitation}"
OUT="${2:-runs/ppo_init}"
shift 2 || shift $# || true
TASKS=("$@")
if [ ${#TASKS[@]} -eq 0 ]; then
    TASKS=(LiftCube-v0 PushCube-v0 PickAndPlaceCube-v0)
fi
for task in "${TASKS[@]}"; do
    dir="$OUT/$task/seed0"
    if [ -f "$dir/protocol.json" ]; then continue; fi
    python -m gym_soarm.train --algo ppo --task "$task" --seed 0 --init "$FROM/$task/seed0" \
        --steps 200000 --eval-every 50000 --vec-env dummy \
        --hyperparams learning_rate=1e-4 --out "$dir" --no-progress
    python -m gym_soarm.evaluate --policy "$dir" --episodes 50 --json "$dir/protocol.json"
done
