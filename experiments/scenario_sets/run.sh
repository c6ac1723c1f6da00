#!/usr/bin/env bash
# The scenario-set study with the main table's PPO stage, end to end and resumable across
# sittings: trains the five run files here into runs/scenario_sets_pr/<set> (a finished run is
# kept, an interrupted one continues from its newest checkpoint with --resume, to the same
# result), averages each run's last six checkpoints into runs/swa/sets_pr_<set>_last6, evaluates
# the averages (averaged/) and the final checkpoints (here) on the nominal and long-tail sets,
# and probes car following.
#
#   cargo build --release --bins --examples && target/release/rtr scenarios generate --out runs/scenarios
#   experiments/scenario_sets/run.sh   # 24-32 min a set on 2 cores, Nom+LT 44, Long-tail 56; 3.2 h in all
set -euo pipefail
cd "$(dirname "$0")/../.."
rtr=target/release/rtr
probe=target/release/examples/car_following
here=experiments/scenario_sets
runs=runs/scenario_sets_pr
for tool in "$rtr" "$probe"; do
    [ -x "$tool" ] || {
        echo "run.sh: $tool not found; build it first with: cargo build --release --bins --examples" >&2
        exit 2
    }
done
[ -d runs/scenarios/train ] || {
    echo "run.sh: runs/scenarios/train not found; draw the scenarios first with: $rtr scenarios generate --out runs/scenarios" >&2
    exit 2
}
sets=(nominal curated longtail nom_cur nom_lt)
for s in "${sets[@]}"; do
    run=$runs/$s
    [ -f "$run/policy.bpk" ] && continue # finished
    # Only the sets that draw generated scenarios need them; the others train as their run file says.
    extra=()
    [[ $s == longtail || $s == nom_lt ]] && extra=(--scenarios runs/scenarios)
    if [ -e "$run/checkpoints/latest" ]; then
        extra+=(--resume)
    elif [ -d "$run" ]; then # stopped before its first checkpoint: nothing to continue from
        echo "run.sh: $run has no checkpoint yet; starting it again" >&2
        rm -rf "$run"
    fi
    $rtr train --config "$here/$s.toml" --out "$run" --keep-checkpoints 6 "${extra[@]}"
done
averages=()
finals=()
for s in "${sets[@]}"; do
    avg=runs/swa/sets_pr_${s}_last6
    sources=()
    for i in 108 099 090 081 072 063; do sources+=(--checkpoint "$runs/$s/checkpoints/iter-000$i"); done
    rm -rf "$avg"
    $rtr model average "${sources[@]}" --out "$avg"
    averages+=(--checkpoint "$avg")
    finals+=(--checkpoint "$runs/$s")
done
$rtr eval "${averages[@]}" --set nominal,longtail --scenarios runs/scenarios --out "$here/averaged"
$rtr eval "${finals[@]}" --set nominal,longtail --scenarios runs/scenarios --out "$here"
# Does any training set teach braking for a slower car ahead? The warm start and each average.
$probe --idm models/il_ff runs/swa/sets_pr_{nominal,curated,longtail,nom_cur,nom_lt}_last6 >"$here/car_following.md.tmp"
mv "$here/car_following.md.tmp" "$here/car_following.md"
