#!/usr/bin/env bash
# Pixel students on one GPU machine (16 cores, one NVIDIA GPU): the CPU recipe of
# docs/learning.md with --device cuda, several runs side by side, each stopped with Ctrl-C
# (SIGINT: checkpoint and curve kept) after LIMIT_S seconds.
#
#   OUT=/tmp/out bash scripts/pixel_students_gpu.sh            # the recipes, several seeds
#                                                              # then each on the protocol
#   OUT=/tmp/out VARIANTS=1 bash scripts/pixel_students_gpu.sh  # recipe variants on Lift
#
# Writes $OUT/pixel_runs.tgz (each run's settings.json, curve.csv, model.pt, log) and
# $OUT/pixel_gpu_summary.json (best success, wall time and rounds of each run).
set -u
OUT=${OUT:-/tmp/pixel_out}
RUNS=${RUNS:-/tmp/pixel_runs}
LIMIT_S=${LIMIT_S:-420}
DEVICE=${DEVICE:-cuda}
PY=${PYTHON:-python3}
mkdir -p "$OUT" "$RUNS"
export MUJOCO_GL=egl PYTHONUNBUFFERED=1
nvidia-smi -L 2>/dev/null || true
$PY -c "import os, torch; print('cpus', os.cpu_count(), 'torch', torch.__version__, 'cuda', torch.cuda.is_available())"

run() {  # run NAME ALGO TASK SEED [KEY=VALUE ...]: the recipe with those values
  local name=$1 algo=$2 task=$3 seed=$4
  shift 4
  local extra=()
  if [ $# -gt 0 ]; then extra=(--hyperparams "$@"); fi
  timeout -s INT "$LIMIT_S" $PY -m gym_soarm.train --algo "$algo" --task "$task" \
    --seed "$seed" --obs-type pixels_agent_pos --camera-config front_wrist \
    --observation-height 96 --observation-width 128 --device "$DEVICE" \
    --out "$RUNS/$name" "${extra[@]}" >"$RUNS/$name.log" 2>&1
  echo "$name exit $?"
}

if [ "${VARIANTS:-0}" = 1 ]; then
  # Which recipe: the default against a faster learning rate, longer training and
  # images pooled to half size before the encoder (Lift, BC and DAgger).
  run lift_bc_default bc LiftCube-v0 0 &
  for seed in 0 1 2; do
    run "lift_bc_fast_s$seed" bc LiftCube-v0 "$seed" learning_rate=1e-3 epochs=60 &
  done
  run lift_bc_fast_pooled bc LiftCube-v0 0 learning_rate=1e-3 epochs=60 downsample=2 &
  run lift_bc_long bc LiftCube-v0 0 learning_rate=1e-3 epochs=100 batch_size=128 &
  run lift_dagger_fast dagger LiftCube-v0 0 learning_rate=1e-3 epochs=40 round_epochs=20 &
  run reach_bc_fast bc ReachTarget-v0 0 learning_rate=1e-3 epochs=60 &
  run push_bc_fast bc PushCube-v0 0 learning_rate=1e-3 epochs=60 &
  wait
else
  # The recipes of docs/learning.md, three seeds on Lift (BC on 200 demonstrations and
  # DAgger) and Reach (DAgger), one on Push.
  for seed in 0 1 2; do
    run "lift_bc_s$seed" bc LiftCube-v0 "$seed" demos=200 &
    run "lift_dagger_s$seed" dagger LiftCube-v0 "$seed" &
    run "reach_dagger_s$seed" dagger ReachTarget-v0 "$seed" &
  done
  run push_dagger_s0 dagger PushCube-v0 0 &
fi
wait

# Each policy on the benchmark's protocol (50 episodes, seeds 1000 + k), side by side.
if [ "${PROTOCOL:-1}" = 1 ]; then
  for dir in "$RUNS"/*/; do
    [ -f "$dir/model.pt" ] || continue
    OMP_NUM_THREADS=1 timeout -s INT "${EVAL_LIMIT_S:-150}" $PY -m gym_soarm.evaluate \
      --policy "$dir" --episodes 50 --json "$dir/protocol.json" >"${dir%/}.eval.log" 2>&1 &
  done
  wait
fi

$PY - "$RUNS" >"$OUT/pixel_gpu_summary.json" <<'PY'
import csv, json, pathlib, sys
root = pathlib.Path(sys.argv[1])
summary = {}
for folder in sorted(p for p in root.iterdir() if p.is_dir()):
    rows = list(csv.DictReader(open(folder / "curve.csv"))) if (folder / "curve.csv").is_file() else []
    summary[folder.name] = {
        "rounds": [
            {k: float(r[k]) for k in ("round", "samples", "wall_s", "success_rate")} for r in rows
        ],
        "best_success": max((float(r["success_rate"]) for r in rows), default=None),
    }
    protocol = folder / "protocol.json"
    if protocol.is_file():
        summary[folder.name]["protocol"] = json.loads(protocol.read_text())
print(json.dumps(summary, indent=1))
PY
cat "$OUT/pixel_gpu_summary.json"
tar czf "$OUT/pixel_runs.tgz" -C "$RUNS" .

# ACT on pixels with LeRobot itself (docs/lerobot.md, "ACT on pixels"): it needs the Python
# 3.12 environment with LeRobot 0.6.1 (not this script's $PY), so it stays commented out:
# DEVICE=cuda NUM_WORKERS=12 WORKERS=8 OUT="$OUT/act_pixels" bash scripts/act_pixels.sh
