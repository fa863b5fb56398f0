#!/usr/bin/env bash
# The imitation baselines of the README's table (SPEC section 22), on this machine:
# DAgger from the state experts on every task, three training seeds each, each policy
# then measured on the benchmark's protocol (50 episodes, seeds 1000 + k).
#   scripts/imitation_baselines.sh [OUT] [TASK ...]
# Each run's folder (model, data, curve) lands in OUT/<task>/seed<k>; its protocol score
# in OUT/<task>/seed<k>/protocol.json. scripts/summarize_imitation.py turns them into
# docs/imitation_baselines.json and docs/imitation_curves.png.
set -euo pipefail
OUT="${1:-runs/imitation}"
shift || true
TASKS=("$@")
if [ ${#TASKS[@]} -eq 0 ]; then
    TASKS=(ReachTarget-v0 LiftCube-v0 PickAndPlaceCube-v0 PushCube-v0
           PickColoredCube-v0 StackCube-v0 PlaceInBin-v0 PickAndPlaceCylinder-v0
           OpenDrawer-v0 SortCubes-v0)
fi
SEEDS="${SEEDS:-0 1 2}"
for seed in $SEEDS; do
    for task in "${TASKS[@]}"; do
        dir="$OUT/$task/seed$seed"
        if [ -f "$dir/protocol.json" ]; then continue; fi
        python -m gym_soarm.train --algo dagger --task "$task" --seed "$seed" --out "$dir" --no-progress
        python -m gym_soarm.evaluate --policy "$dir" --episodes 50 --json "$dir/protocol.json"
    done
done
