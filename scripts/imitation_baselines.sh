#!/usr/bin/env bash
# The imitation baselines of docs/learning.md (SPEC section 22), on this machine:
# behaviour cloning (ALGO=bc, the default; or ALGO=dagger) from the state experts on every
# task, three training seeds each, each policy then measured on the benchmark's protocol
# (50 episodes, seeds 1000 + k). Two workers share the tasks, one per CPU core.
#   scripts/imitation_baselines.sh [OUT] [TASK ...]
# Each run's folder (model, data, curve) lands in OUT/<task>/seed<k>; its protocol score
# in OUT/<task>/seed<k>/protocol.json. Then
#   python scripts/summarize_rl.py OUT --json docs/imitation_baselines.json \
#       --plot docs/imitation_curves.png
set -euo pipefail
OUT="${1:-runs/imitation}"
shift || true
TASKS=("$@")
if [ ${#TASKS[@]} -eq 0 ]; then
    TASKS=(ReachTarget-v0 LiftCube-v0 PickAndPlaceCube-v0 PushCube-v0
           PickColoredCube-v0 StackCube-v0 PlaceInBin-v0 PickAndPlaceCylinder-v0
           OpenDrawer-v0 SortCubes-v0)
fi
ALGO="${ALGO:-bc}"
SEEDS="${SEEDS:-0 1 2}"
WORKERS="${WORKERS:-2}"

run() {  # run TASK SEED: train, then score on the protocol (skipped when done)
    local dir="$OUT/$1/seed$2"
    if [ -f "$dir/protocol.json" ]; then return; fi
    python -m gym_soarm.train --algo "$ALGO" --task "$1" --seed "$2" --out "$dir" --no-progress
    python -m gym_soarm.evaluate --policy "$dir" --episodes 50 --json "$dir/protocol.json"
}

worker() {  # worker I: every WORKERS-th (task, seed) pair, seeds in order
    local index=0
    for seed in $SEEDS; do
        for task in "${TASKS[@]}"; do
            if [ $((index % WORKERS)) -eq "$1" ]; then run "$task" "$seed"; fi
            index=$((index + 1))
        done
    done
}

for ((i = 0; i < WORKERS; i++)); do worker "$i" & done
wait
