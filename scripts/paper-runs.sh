#!/bin/bash
# The paper's scenarios (Exp. 1, Exp. 2, the 24 cm step), seeds 0-9 each, under four
# conditions: the loop on the simulator's truth or on the robot's own estimate, in the model's
# body or an `hrp4-like` one. One `run --json` report per run, in OUT/<condition>/; then
# `scripts/side-by-side.py` tabulates them (BENCHMARKS.md shows the command).
# Usage: scripts/paper-runs.sh OUT [BIN [CONDITION...]] (BIN defaults to
# ./target/release/stairbench; the conditions, to all four: truth-model estimate-model
# truth-hrp4 estimate-hrp4).
set -euo pipefail
OUT=${1:?usage: scripts/paper-runs.sh OUT [BIN]}
BIN=${2:-./target/release/stairbench}
declare -A FLAGS=(
    [truth-model]="--estimate off"
    [estimate-model]="--estimate on"
    [truth-hrp4]="--estimate off --plant hrp4-like"
    [estimate-hrp4]="--estimate on --plant hrp4-like"
)
CONDITIONS=("${@:3}")
[ ${#CONDITIONS[@]} -gt 0 ] || CONDITIONS=(truth-model estimate-model truth-hrp4 estimate-hrp4)
for cond in "${CONDITIONS[@]}"; do
    [ -n "${FLAGS[$cond]+set}" ] || { echo "paper-runs: no condition '$cond'" >&2; exit 2; }
    mkdir -p "$OUT/$cond"
    for sc in exp1 exp2 hrp4_step; do
        for seed in 0 1 2 3 4 5 6 7 8 9; do
            # shellcheck disable=SC2086 # the flags are words
            "$BIN" run "$sc" --seed "$seed" ${FLAGS[$cond]} --json "$OUT/$cond/$sc-$seed.json" >/dev/null ||
                echo "paper-runs: $cond $sc seed $seed failed (see its report)"
        done
    done
    echo "paper-runs: $cond done"
done
