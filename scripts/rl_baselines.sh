#!/usr/bin/env bash
# The RL baselines of docs/learning.md: each (algorithm, task) with three training seeds on the
# package's recipe (gym_soarm/rl/hyperparams.py), then 50 protocol episodes per policy
# (seeds 1000-1049) and the summary (docs/rl_baselines.json, docs/rl_curves.png).
#
#   bash scripts/rl_baselines.sh                       # PPO and SAC on ReachTarget-v0
#   RUNS="ppo:LiftCube-v0" bash scripts/rl_baselines.sh
#
# Needs the rl extra: pip install -e ".[rl]" (a CPU-only PyTorch is enough).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-runs}"
RUNS="${RUNS:-ppo:ReachTarget-v0 sac:ReachTarget-v0}"
SEEDS="${SEEDS:-0 1 2}"
EPISODES="${EPISODES:-50}"
export MUJOCO_GL="${MUJOCO_GL:-egl}"

for run in $RUNS; do
    algo="${run%%:*}"
    task="${run#*:}"
    for seed in $SEEDS; do
        dir="$OUT/${algo}_${task}_s${seed}"
        python -m gym_soarm.train --algo "$algo" --task "$task" --seed "$seed" --out "$dir" \
            --no-progress
        python -m gym_soarm.evaluate --policy "$dir" --episodes "$EPISODES" \
            --json "$dir/protocol.json"
    done
done
python scripts/summarize_rl.py "$OUT" --json docs/rl_baselines.json --plot docs/rl_curves.png
