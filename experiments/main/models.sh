#!/usr/bin/env bash
# Trains the main comparison's models from their run files and writes each as the weight
# average of its run's last six checkpoints into models/<method>_main (policy.bpk, config.toml,
# averaged.json, and the run's curves.csv; the cards are written by hand from these). The same
# PPO stage also trains the ablations' models: KL-L and KL-R (imitation signal,
# ../imitation_signal/) and RL with scene-level PPO (../ppo_ablation/).
#
#   cargo build --release && target/release/rtr scenarios generate --out runs/scenarios
#   experiments/main/models.sh                  # the six main methods, about 2.8 h alone on 2 cores
#   experiments/main/models.sh rtr bc_rl        # some of them
#   experiments/main/models.sh kl_l kl_r rl_scene_level   # the ablations, about 40 min each
#
# Warm starts: the PPO methods start from models/il_ff and models/bc_ff, IL from
# models/il_recipe (all shipped). BC starts from models/bc_recipe, which is not shipped:
# restore it from git (git checkout 2b50027 -- models/bc_recipe) or train it from scratch with
# bc_stage1.toml and bc_stage1_us101.toml (README.md, "Commands").
#
# Training is deterministic on the Flex CPU backend: a rerun writes the same weights. The
# committed PPO models (rtr, bc_rl, rl, rl_shaped) were trained after commit 3d0020c, which
# made warm-started PPO runs train the action head's output biases (README.md, "The bias fix").
# Runs go to runs/main_models/<method>; rerunning the script continues an interrupted run.
set -euo pipefail
cd "$(dirname "$0")/../.."
rtr=target/release/rtr
[ -x "$rtr" ] || {
    echo "models.sh: $rtr not found; build it first with: cargo build --release" >&2
    exit 2
}

# Runs a run file into runs/main_models/<name>, then averages the given checkpoints. A finished
# run is averaged again without training; an interrupted one continues from its newest
# checkpoint (--resume, to the same result); one stopped before its first checkpoint starts over.
train_and_average() {
    local name=$1 config=$2 extra=$3
    shift 3
    local run=runs/main_models/$name out=models/${name}_main
    if [ ! -f "$run/policy.bpk" ]; then
        if [ -e "$run/checkpoints/latest" ]; then
            extra="$extra --resume"
        elif [ -d "$run" ]; then
            echo "models.sh: $run has no checkpoint yet; starting it again" >&2
            rm -rf "$run"
        fi
        # shellcheck disable=SC2086 # $extra is a list of flags
        $rtr train --config "$config" --out "$run" $extra
    fi
    local sources=()
    for i in "$@"; do sources+=(--checkpoint "$run/checkpoints/iter-000$i"); done
    rm -rf "$out.tmp"
    $rtr model average "${sources[@]}" --out "$out.tmp"
    cp "$run/curves.csv" "$out.tmp/"
    [ -f "$out/CARD.md" ] && cp "$out/CARD.md" "$out.tmp/"
    rm -rf "$out" && mv "$out.tmp" "$out"
}

# BC and IL: 432 optimizer steps, checkpoints every 25 (kept) and the final one.
supervised=(432 425 400 375 350 325)
# PPO methods: 108 iterations, a checkpoint every 9.
ppo=(108 099 090 081 072 063)
ppo_flags="--scenarios runs/scenarios --keep-checkpoints 6"

methods=("$@")
main=(il bc rtr bc_rl rl rl_shaped)
known=("${main[@]}" kl_l kl_r rl_scene_level)
[ ${#methods[@]} -eq 0 ] && methods=("${main[@]}")
for m in "${methods[@]}"; do # every name checked before hours of training start
    [[ " ${known[*]} " == *" $m "* ]] || {
        echo "models.sh: unknown method '$m' (expected one of: ${known[*]})" >&2
        exit 2
    }
done
# The PPO methods draw long-tail scenarios; BC and IL train on the recordings alone.
if [[ " ${methods[*]} " =~ \ (rtr|bc_rl|rl|rl_shaped|kl_l|kl_r|rl_scene_level)\  ]] && [ ! -d runs/scenarios/train ]; then
    echo "models.sh: runs/scenarios/train not found; draw the scenarios first with: $rtr scenarios generate --out runs/scenarios" >&2
    exit 2
fi
# BC starts from a stage model that is not shipped (see the top of this file).
for m in "${methods[@]}"; do
    case $m in il) warm=models/il_recipe ;; bc) warm=models/bc_recipe ;; *) continue ;; esac
    [ -f "$warm/policy.bpk" ] || [ -f "runs/main_models/$m/policy.bpk" ] || {
        echo "models.sh: $m starts from $warm, which is not shipped; restore it with: git checkout 2b50027 -- $warm (or train it: experiments/main/README.md, \"Commands\")" >&2
        exit 2
    }
done
for m in "${methods[@]}"; do
    case $m in
    il) train_and_average il experiments/main/il.toml "--keep-checkpoints 20" "${supervised[@]}" ;;
    bc) train_and_average bc experiments/main/bc.toml "--keep-checkpoints 20" "${supervised[@]}" ;;
    rtr) train_and_average rtr experiments/main/rtr.toml "$ppo_flags" "${ppo[@]}" ;;
    bc_rl | rl | rl_shaped) train_and_average "$m" "experiments/main/$m.toml" "$ppo_flags" "${ppo[@]}" ;;
    kl_l | kl_r) train_and_average "$m" "experiments/imitation_signal/$m.toml" "$ppo_flags" "${ppo[@]}" ;;
    rl_scene_level) train_and_average "$m" experiments/ppo_ablation/rl_scene_level.toml "$ppo_flags" "${ppo[@]}" ;;
    esac
done
