#!/usr/bin/env bash
# Trains the main comparison's models from their run files into models/<method>_main
# (policy.bpk, config.toml and the run's curves.csv; averaged.json for the PPO methods; the
# cards are written by hand from these):
# - IL and BC: two stages each (il_stage1.toml then il.toml; bc_stage1.toml then bc.toml); the
#   model is the second stage's final policy, which the PPO methods start from (they read it
#   from the run folder, runs/main_models/il or runs/main_models/bc, so train IL or BC first);
# - RTR, RL, RL-Shaped, BC+RL: the weight average of the run's last six checkpoints (one per
#   epoch of 1,728 initial states).
#
#   cargo build --release && target/release/rtr scenarios generate --out runs/scenarios
#   experiments/main/models.sh                  # all six, in this order (hours: README.md)
#   experiments/main/models.sh rtr rl           # some of them
#
# Runs go to runs/main_models/<name>. Rerunning the script continues an interrupted run from its
# newest checkpoint (--resume, to the same weights: training is deterministic on the Flex CPU
# backend) and skips what has finished; a run stopped before its first checkpoint starts over.
set -euo pipefail
cd "$(dirname "$0")/../.."
rtr=target/release/rtr
[ -x "$rtr" ] || {
    echo "models.sh: $rtr not found; build it first with: cargo build --release" >&2
    exit 2
}

# Trains run file $2 into runs/main_models/$1 with the extra flags $3, unless it has finished.
train() {
    local run=runs/main_models/$1 config=$2 extra=$3
    [ -f "$run/policy.bpk" ] && return
    if [ -e "$run/checkpoints/latest" ]; then
        extra="$extra --resume"
    elif [ -d "$run" ]; then
        echo "models.sh: $run has no checkpoint yet; starting it again" >&2
        rm -rf "$run"
    fi
    # shellcheck disable=SC2086 # $extra is a list of flags
    $rtr train --config "$config" --out "$run" $extra
}

# Replaces models/$1 with the folder $2 (built beside it first, so an interrupted copy never
# leaves a half model), keeping the model's hand-written card.
install_model() {
    local out=models/$1 built=$2
    [ -f "$out/CARD.md" ] && cp "$out/CARD.md" "$built/"
    rm -rf "$out" && mv "$built" "$out"
}

# IL or BC: stage 1 from scratch, stage 2 from it; the model is stage 2's final policy.
supervised() {
    local m=$1 run=runs/main_models/$1
    train "${m}_stage1" "experiments/main/${m}_stage1.toml" ""
    train "$m" "experiments/main/$m.toml" ""
    rm -rf "models/${m}_main.tmp" && mkdir -p "models/${m}_main.tmp"
    cp "$run/policy.bpk" "$run/config.toml" "$run/curves.csv" "models/${m}_main.tmp/"
    install_model "${m}_main" "models/${m}_main.tmp"
}

# A PPO method: the run, then the weight average of its last six checkpoints.
ppo() {
    local m=$1 run=runs/main_models/$1
    local warm=runs/main_models/il
    [ "$m" = bc_rl ] && warm=runs/main_models/bc
    if [ ! -f "$run/checkpoints/latest" ] && [ ! -f "$run/policy.bpk" ] && [ ! -f "$warm/policy.bpk" ]; then
        echo "models.sh: $m starts from $warm/policy.bpk, which is not there; train it first: experiments/main/models.sh ${warm##*/}" >&2
        exit 2
    fi
    train "$m" "experiments/main/$m.toml" "--scenarios runs/scenarios --keep-checkpoints 100"
    local sources=()
    for c in $(find "$run/checkpoints" -maxdepth 1 -name 'iter-*' | sort | tail -n 6); do
        sources+=(--checkpoint "$c")
    done
    rm -rf "models/${m}_main.tmp"
    $rtr model average "${sources[@]}" --out "models/${m}_main.tmp"
    cp "$run/curves.csv" "models/${m}_main.tmp/"
    install_model "${m}_main" "models/${m}_main.tmp"
}

methods=("$@")
main=(il bc rtr rl rl_shaped bc_rl)
[ ${#methods[@]} -eq 0 ] && methods=("${main[@]}")
for m in "${methods[@]}"; do # every name checked before hours of training start
    [[ " ${main[*]} " == *" $m "* ]] || {
        echo "models.sh: unknown method '$m' (expected one of: ${main[*]})" >&2
        exit 2
    }
done
# The PPO methods draw long-tail scenarios; BC and IL train on the recordings alone.
if [[ " ${methods[*]} " =~ \ (rtr|bc_rl|rl|rl_shaped)\  ]] && [ ! -d runs/scenarios/train ]; then
    echo "models.sh: runs/scenarios/train not found; draw the scenarios first with: $rtr scenarios generate --out runs/scenarios" >&2
    exit 2
fi
for m in "${methods[@]}"; do
    case $m in
    il | bc) supervised "$m" ;;
    *) ppo "$m" ;;
    esac
done
