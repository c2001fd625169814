#!/usr/bin/env bash
# Setup step: the learned VLA / VTLA-real / VTLA-pred policies of both tasks in
# .build/models/learned, and the demonstrations they are trained on as LeRobot v3.0 datasets.
#   1. `unitac demos` records the scripted expert on the TRAINING objects of each task (seeds
#      1,2,3 x 20 trials), the vtla_real and vtla_pred scenes' tactile stages watching the same
#      trials, so every tick carries every mode's observations;
#   2. scripts/lerobot_dataset.py lays them out in .build/models/learned/datasets/<task> (LeRobot
#      v3.0);
#   3. models/train_policy.py trains the 3 modes x 2 tasks once per training seed (0, 1, 2) into
#      .build/models/learned/seed<k>/<task>_<mode> (ONNX + manifest.json) and checks ONNX Runtime
#      against its numpy forward.
# UNITAC_DAGGER=1 (opt-in, not a setup step: its retrained policies did worse in closed loop,
# crates/policy/README.md "DAgger") adds one round of DAgger per training seed: each first-round
# policy drives the world on the training objects (`unitac demos --drive`, draw seed 4,
# DAGGER_TRIALS trials), every tick labelled with the expert's command there, laid out as LeRobot
# datasets (.build/models/learned/dagger/seed<k>/<task>_<mode>), and models/train_policy.py
# --dagger trains each seed's policies again on the demonstrations plus its own DAgger states.
# Needs steps 5 and 6 of scripts/setup.sh (the reference and touch bundles the scenes load).
# Skipped when its inputs did not change (a stamp of them in .build/models/learned/.stamp).
# UNITAC_LEARNED puts it elsewhere (the policy tests read it too).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# The ONNX Runtime library and the model paths the scenes name.
source scripts/env.sh
VENV="${UNITAC_VENV:-$ROOT/.venv}"
MODELS="$ROOT/.build/models"
export UNITAC_MODELS="${UNITAC_MODELS:-$MODELS}"
OUT="${UNITAC_LEARNED:-$MODELS/learned}"
TASKS=(cup_deformation fabric_selection)
SEEDS=(0 1 2)
MODES=(vla vtla_real vtla_pred)
DAGGER="${UNITAC_DAGGER:-0}"
DAGGER_SEED=4
DAGGER_TRIALS=4
log() { printf '[setup] %s\n' "$*" >&2; }

inputs=(scripts/learned_policies.sh scripts/lerobot_dataset.py models/train_policy.py
  models/generate_reference.py Cargo.lock crates/cli/src/demos.rs crates/cli/src/main.rs
  launch/scenes/*_learned_*.yaml
  launch/scenes/cup_deformation_vtla_real.yaml launch/scenes/cup_deformation_vtla_pred.yaml
  launch/scenes/fabric_selection_vtla_real.yaml launch/scenes/fabric_selection_vtla_pred.yaml
  $(find crates/sim/src crates/contact/src crates/core/src crates/infer/src crates/trials/src crates/pipeline/src crates/policy/src -name '*.rs' | sort))
key="$( (cat "${inputs[@]}" "$MODELS/.stamp" "$MODELS/touch/.stamp" 2>/dev/null; echo "dagger $DAGGER") | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$OUT/.stamp" 2>/dev/null)" = "$key" ] \
  && [ -f "$OUT/seed${SEEDS[-1]}/${TASKS[-1]}_vtla_pred/manifest.json" ]; then
  exit 0
fi
log "learned policies: demonstrations of both tasks on training objects, LeRobot datasets, training"
start=$SECONDS
cargo build --release --locked -q -p unitac-cli
rm -rf "$OUT.tmp"
mkdir -p "$OUT.tmp"
sets=()
for task in "${TASKS[@]}"; do
  target/release/unitac demos --scene "${task}_vtla_real,${task}_vtla_pred" --split train \
    --seeds 1,2,3 --trials 20 --out "$OUT.tmp/demos/$task" >&2
  "$VENV/bin/python" scripts/lerobot_dataset.py --demos "$OUT.tmp/demos/$task/demos.json" \
    --out "$OUT.tmp/datasets/$task" >&2
  sets+=(--dataset "$OUT.tmp/datasets/$task")
done
rm -rf "$OUT.tmp/demos"
first="$OUT.tmp"
[ "$DAGGER" = 1 ] && first="$OUT.tmp/round0"
for seed in "${SEEDS[@]}"; do
  "$VENV/bin/python" models/train_policy.py "${sets[@]}" --seed "$seed" --out "$first/seed$seed" >/dev/null
done
for seed in "${SEEDS[@]}"; do
  [ "$DAGGER" = 1 ] || break
  [ "$seed" = "${SEEDS[0]}" ] && log "learned policies: first round $((SECONDS - start)) s; DAgger"
  for task in "${TASKS[@]}"; do
    for mode in "${MODES[@]}"; do
      d="$OUT.tmp/dagger/seed$seed/${task}_$mode"
      target/release/unitac demos --scene "${task}_vtla_real,${task}_vtla_pred" --split train \
        --seeds "$DAGGER_SEED" --trials "$DAGGER_TRIALS" --drive "${task}_learned_$mode" \
        --drive-model "$OUT.tmp/round0/seed$seed/${task}_$mode/manifest.json" --out "$d.demos" >&2
      "$VENV/bin/python" scripts/lerobot_dataset.py --demos "$d.demos/demos.json" --out "$d" >&2
      rm -rf "$d.demos"
    done
  done
  "$VENV/bin/python" models/train_policy.py "${sets[@]}" --seed "$seed" \
    --dagger "$OUT.tmp/dagger/seed$seed" --out "$OUT.tmp/seed$seed" >/dev/null
done
rm -rf "$OUT.tmp/round0"
"$VENV/bin/python" models/train_policy.py --check-onnx "$OUT.tmp/seed0" "${sets[@]}" >/dev/null
rm -rf "$OUT"
mv "$OUT.tmp" "$OUT"
echo "$key" >"$OUT/.stamp"
log "learned policies: $((SECONDS - start)) s"
