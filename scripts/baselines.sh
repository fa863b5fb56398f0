#!/usr/bin/env bash
# State-based ACT baselines on the soarm_core suite, on CPU, with LeRobot itself.
#
# For each task: record the scripted expert (state only, LeRobot units), train a small
# ACT with lerobot-train, score it with lerobot-eval on the evaluation protocol (episode k
# resets with seed 1000 + k, lerobot-eval's default --seed), and append one JSON line of
# figures to $OUT/results.jsonl. Run it in the Python 3.12 environment that has LeRobot:
#
#     pip install "lerobot[dataset,training]==0.6.1" -e ".[lerobot]" -e plugins/lerobot_env_soarm
#     bash scripts/baselines.sh            # TASKS, EPISODES, STEPS, EVAL_EPISODES, OUT
#
# Every command below is the exact one behind the baseline table of docs/lerobot.md.
set -euo pipefail
TASKS="${TASKS:-ReachTarget-v0 LiftCube-v0 PickAndPlaceCube-v0 PushCube-v0}"
EPISODES="${EPISODES:-50}"
STEPS="${STEPS:-1000}"
EVAL_EPISODES="${EVAL_EPISODES:-50}"
OUT="${OUT:-outputs/baselines}"
export HF_HUB_OFFLINE=1 WANDB_MODE=disabled
mkdir -p "$OUT"

for task in $TASKS; do
    name="$(echo "${task%-v*}" | tr '[:upper:]' '[:lower:]')"
    data="$OUT/datasets/$name"
    train="$OUT/train/$name"
    eval_dir="$OUT/eval/$name"
    rm -rf "$train" "$eval_dir"
    t0=$(date +%s)
    python -m gym_soarm.record --task "$task" --episodes "$EPISODES" --seed 0 \
        --camera-config none --root "$data" --repo-id "local/soarm_${name}_state" \
        --overwrite --no-progress
    t1=$(date +%s)
    lerobot-train --dataset.repo_id="local/soarm_${name}_state" --dataset.root="$data" \
        --policy.type=act --policy.device=cpu --policy.push_to_hub=false --wandb.enable=false \
        --policy.dim_model=256 --policy.n_heads=8 --policy.dim_feedforward=1024 \
        --policy.n_encoder_layers=2 --policy.n_decoder_layers=1 --policy.use_vae=false \
        --policy.chunk_size=20 --policy.n_action_steps=10 --policy.optimizer_lr=1e-4 \
        --steps="$STEPS" --batch_size=64 --num_workers=0 --log_freq=200 \
        --save_freq="$STEPS" --seed=0 --output_dir="$train" > "$OUT/train_$name.log" 2>&1
    t2=$(date +%s)
    lerobot-eval --env.type=soarm --env.task="$task" \
        --env.obs_type=environment_state_agent_pos \
        --env.observation_height=240 --env.observation_width=320 \
        --policy.path="$train/checkpoints/last/pretrained_model" --policy.device=cpu \
        --eval.n_episodes="$EVAL_EPISODES" --eval.batch_size=10 \
        --output_dir="$eval_dir" > "$OUT/eval_$name.log" 2>&1
    t3=$(date +%s)
    python - "$task" "$eval_dir/eval_info.json" "$EPISODES" "$STEPS" \
        $((t1 - t0)) $((t2 - t1)) $((t3 - t2)) >> "$OUT/results.jsonl" <<'PY'
import json, sys
task, info_path, episodes, steps, rec_s, train_s, eval_s = sys.argv[1:]
info = json.load(open(info_path))
overall = info["overall"]
print(json.dumps({
    "task": task, "demonstrations": int(episodes), "train_steps": int(steps),
    "eval_episodes": overall["n_episodes"], "pc_success": overall["pc_success"],
    "avg_max_reward": overall["avg_max_reward"],
    "record_s": int(rec_s), "train_s": int(train_s), "eval_s": int(eval_s),
}))
PY
    tail -1 "$OUT/results.jsonl"
done
