#!/usr/bin/env bash
# The shipped platesynth segmentation model (models/plaque12): synthetic 12-well plates only, trained on a CPU
# (about 15 minutes on 2 free cores).
#
#   scripts/train_model.sh                       # renders 750 images into $DATA, trains into $MODEL
#   DATA=/scratch/plates MODEL=/scratch/model THREADS=4 scripts/train_model.sh
#   HIGH_CONFIG=my-look.yaml scripts/train_model.sh   # the high part with a configuration over the preset
#
# Thresholds (probability, NMS, countability) are tuned on held-out synthetic images only. Then, zero-shot on the
# real plates, on the fit and check halves:  python benchmarks/zero_shot_counts.py --models "$MODEL"
set -euo pipefail
DATA=${DATA:-runs/plaque12-data}
MODEL=${MODEL:-runs/plaque12}
THREADS=${THREADS:-2}
EPOCHS=${EPOCHS:-40}
STEPS=${STEPS:-50}
HIGH_CONFIG=${HIGH_CONFIG:-}

# preset, images, seed, overrides: rendered at the model's working size (512 px); fewer negative plates than the
# preset's half, so that more training patches hold plaques
render() {
    platesynth render --out "$DATA/$1" --count "$2" --seed "$3" --preset "$1" --plate 12 --size 512x384 \
        --workers "$THREADS" "${@:4}"
}
render high 450 201 --set plaques.negative_plate=0.2 ${HIGH_CONFIG:+--config "$HIGH_CONFIG"}
render medium 150 202
render diverse 150 204

platesynth train \
    --data "$DATA/high" --data "$DATA/medium" --data "$DATA/diverse" --mix 0.6,0.2,0.2 \
    --out "$MODEL" --epochs "$EPOCHS" --steps "$STEPS" --batch-size 4 --patch 256x256 --lr 2e-3 \
    --val-fraction 0.03 --max-val 16 --seed 0 --threads "$THREADS" --workers 1
