#!/usr/bin/env bash
# The first platesynth segmentation model: synthetic 12-well plates only, trained on a CPU in about 25 minutes (2 busy cores).
#
#   scripts/train_first_model.sh                 # renders 550 images into $DATA, trains into $MODEL
#   DATA=/scratch/plates MODEL=/scratch/model THREADS=4 scripts/train_first_model.sh
#
# The shipped models/plaque12-synthetic holds weights.pt, config.json and history.json of such a run.
#
# Then, zero-shot on the real plates (a person's counts; blank wells are not scored):
#   platesynth evaluate counts --model "$MODEL" --images ../shared/data/plaque12/plates \
#       --counts ../shared/data/plaque12/counts.csv --json
set -euo pipefail
DATA=${DATA:-runs/first-model-data}
MODEL=${MODEL:-runs/plaque12-synthetic}
# One torch thread: on a busy 2-core machine more threads spin-wait each other and run many times slower.
THREADS=${THREADS:-1}

# preset, images, seed: 550 images at 512x384 (the model's working size), about 10 minutes with one process
for spec in "high 200 101" "medium 150 102" "low 100 103" "diverse 100 104"; do
    set -- $spec
    platesynth render --out "$DATA/$1" --count "$2" --seed "$3" --preset "$1" --plate 12 --size 512x384
done

# 20 epochs x 40 steps x 4 patches of 256x256, 5% of each dataset held out for the
# validation loss and the threshold tuning (16 images at most); one data-loading process beside the training thread.
platesynth train \
    --data "$DATA/high" --data "$DATA/medium" --data "$DATA/low" --data "$DATA/diverse" \
    --out "$MODEL" --epochs 20 --steps 40 --batch-size 4 --patch 256x256 --lr 2e-3 \
    --val-fraction 0.05 --max-val 16 --seed 0 --threads "$THREADS" --workers 1
