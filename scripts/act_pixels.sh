#!/usr/bin/env bash
# ACT on pixels with LeRobot itself: front and wrist cameras at 96 x 128, no pretrained
# backbone weights (resnet18 from scratch), one task.
#
# Records the state expert of TASK with DART noise (front + wrist, 96 x 128, 30 fps), trains
# LeRobot's ACT with lerobot-train, saves a checkpoint every SAVE_FREQ steps, scores each
# checkpoint with lerobot-eval on the evaluation protocol (episode k resets with seed
# 1000 + k, lerobot-eval's default --seed; the same two cameras at the same size and rate):
# MID_EVAL_EPISODES episodes for the intermediate checkpoints, EVAL_EPISODES for the last,
# and appends one JSON line per checkpoint to $OUT/results.jsonl. Run it in the Python 3.12
# environment that has LeRobot:
#
#     pip install "lerobot[dataset,training]==0.6.1" -e ".[lerobot]" -e plugins/lerobot_env_soarm
#     bash scripts/act_pixels.sh                     # CPU, the defaults below
#     DEVICE=cuda NUM_WORKERS=12 WORKERS=8 bash scripts/act_pixels.sh   # one GPU machine
#
# Variables: TASK, EPISODES, DART_NOISE, CONTROL_HZ, SIZE, STEPS, BATCH, SAVE_FREQ, LR,
# CHUNK_SIZE, N_ACTION_STEPS, DEVICE, NUM_WORKERS (dataloader), WORKERS (recorder),
# EVAL_EPISODES, MID_EVAL_EPISODES, EVAL_BATCH, ACT_ARGS (more --policy.* flags), OUT.
# An existing dataset in $OUT/datasets is reused (RERECORD=1 records it again).
set -euo pipefail
TASK="${TASK:-LiftCube-v0}"
EPISODES="${EPISODES:-100}"
DART_NOISE="${DART_NOISE:-0.01}"
CONTROL_HZ="${CONTROL_HZ:-30}"
SIZE="${SIZE:-96x128}"
STEPS="${STEPS:-6000}"
BATCH="${BATCH:-16}"
SAVE_FREQ="${SAVE_FREQ:-$(( STEPS >= 6 ? STEPS / 6 : 1 ))}"
LR="${LR:-1e-4}"
CHUNK_SIZE="${CHUNK_SIZE:-20}"
N_ACTION_STEPS="${N_ACTION_STEPS:-10}"
DEVICE="${DEVICE:-cpu}"
if [ "$DEVICE" = cpu ]; then NUM_WORKERS="${NUM_WORKERS:-0}"; else NUM_WORKERS="${NUM_WORKERS:-8}"; fi
WORKERS="${WORKERS:-1}"
EVAL_EPISODES="${EVAL_EPISODES:-50}"
MID_EVAL_EPISODES="${MID_EVAL_EPISODES:-10}"
EVAL_BATCH="${EVAL_BATCH:-10}"
# A smaller transformer than LeRobot's default (dim_model 512, feed-forward 3200, the VAE):
# about 2.5 times cheaper a step on a CPU; the expert's demonstrations need no VAE.
ACT_ARGS="${ACT_ARGS:---policy.dim_model=256 --policy.dim_feedforward=1024 --policy.use_vae=false}"
OUT="${OUT:-runs/act_pixels}"  # runs/ is ignored by git
export HF_HUB_OFFLINE=1 WANDB_MODE=disabled
export MUJOCO_GL="${MUJOCO_GL:-egl}"
height="${SIZE%x*}"
width="${SIZE#*x}"
log_freq=$(( SAVE_FREQ < 100 ? SAVE_FREQ : 100 ))
while [ $(( SAVE_FREQ % log_freq )) -ne 0 ]; do log_freq=$(( log_freq - 1 )); done

name="$(echo "${TASK%-v*}" | tr '[:upper:]' '[:lower:]')"
repo="local/soarm_${name}_pixels"
data="$OUT/datasets/$name"
train="$OUT/train/$name"
mkdir -p "$OUT"

t0=$(date +%s)
if [ "${RERECORD:-0}" = 1 ] || [ ! -f "$data/meta/info.json" ]; then
    python -m gym_soarm.record --task "$TASK" --episodes "$EPISODES" --seed 0 \
        --camera-config front_wrist --size "$SIZE" --control-hz "$CONTROL_HZ" \
        --dart-noise "$DART_NOISE" --workers "$WORKERS" \
        --root "$data" --repo-id "$repo" --overwrite --no-progress
fi
t1=$(date +%s)

# ACT for 96 x 128 images from scratch: LeRobot's resnet18 (3 x 4 feature maps, 12 tokens a
# camera; torchvision's resnet18 cannot trade its last stride for dilation), trained at the
# transformer's learning rate (LR, 1e-4: ten times LeRobot's fine-tuning rate, as nothing is
# pretrained); chunks of CHUNK_SIZE actions (20: 0.67 s at 30 fps, over a third of an
# expert's lift of about 55 frames) of which N_ACTION_STEPS (10: 0.33 s) run before the
# policy looks again.
rm -rf "$train"
# shellcheck disable=SC2086  # ACT_ARGS: several flags
lerobot-train --dataset.repo_id="$repo" --dataset.root="$data" --dataset.video_backend=pyav \
    --policy.type=act --policy.pretrained_backbone_weights=null \
    --policy.vision_backbone=resnet18 \
    --policy.chunk_size="$CHUNK_SIZE" --policy.n_action_steps="$N_ACTION_STEPS" \
    --policy.optimizer_lr="$LR" --policy.optimizer_lr_backbone="$LR" \
    --policy.device="$DEVICE" --policy.push_to_hub=false --wandb.enable=false $ACT_ARGS \
    --steps="$STEPS" --batch_size="$BATCH" --num_workers="$NUM_WORKERS" \
    --log_freq="$log_freq" --save_freq="$SAVE_FREQ" --seed=0 \
    --output_dir="$train" > "$OUT/train_$name.log" 2>&1
t2=$(date +%s)

for checkpoint in "$train"/checkpoints/[0-9]*/; do
    step="$(basename "$checkpoint")"
    step=$(( 10#$step ))
    if [ "$step" -eq "$STEPS" ]; then n="$EVAL_EPISODES"; else n="$MID_EVAL_EPISODES"; fi
    eval_dir="$OUT/eval/${name}_$step"
    rm -rf "$eval_dir"
    t3=$(date +%s)
    lerobot-eval --env.type=soarm --env.task="$TASK" --env.obs_type=pixels_agent_pos \
        --env.camera_config=front_wrist --env.fps="$CONTROL_HZ" \
        --env.observation_height="$height" --env.observation_width="$width" \
        --policy.path="${checkpoint}pretrained_model" --policy.device="$DEVICE" \
        --eval.n_episodes="$n" --eval.batch_size="$(( n < EVAL_BATCH ? n : EVAL_BATCH ))" \
        --output_dir="$eval_dir" > "$OUT/eval_${name}_$step.log" 2>&1
    t4=$(date +%s)
    python - "$TASK" "$eval_dir/eval_info.json" "$data/meta/info.json" "$OUT/train_$name.log" \
        "${checkpoint}pretrained_model" "$EPISODES" "$DART_NOISE" "$step" "$STEPS" \
        "$log_freq" "$BATCH" "$DEVICE" "$t1" $((t1 - t0)) $((t2 - t1)) $((t4 - t3)) \
        >> "$OUT/results.jsonl" <<'PY'
import json, os, re, sys
(task, info_path, data_info, train_log, model_dir, episodes, dart, step, steps, log_freq,
 batch, device, train_start, rec_s, train_s, eval_s) = sys.argv[1:]
overall = json.load(open(info_path))["overall"]
data = json.load(open(data_info))
losses = re.findall(r"\bloss:([0-9.]+)", open(train_log).read())
logged = int(step) // int(log_freq)
model = os.path.join(model_dir, "model.safetensors")
print(json.dumps({
    "task": task, "policy": "act", "cameras": "front_wrist",
    "image_size": [data["features"][k]["shape"][:2] for k in data["features"]
                   if k.startswith("observation.images.")][0],
    "fps": data["fps"], "demonstrations": data["total_episodes"],
    "demonstration_frames": data["total_frames"], "dart_noise": float(dart),
    "train_steps": int(step), "planned_steps": int(steps), "batch_size": int(batch),
    "device": device,
    "loss": float(losses[logged - 1]) if 0 < logged <= len(losses) else None,
    "eval_episodes": overall["n_episodes"], "pc_success": overall["pc_success"],
    "avg_max_reward": overall["avg_max_reward"],
    "record_s": int(rec_s),
    "train_s_at_checkpoint": int(os.path.getmtime(model) - int(train_start)),
    "train_s": int(train_s), "eval_s": int(eval_s),
}))
PY
    tail -1 "$OUT/results.jsonl"
done
