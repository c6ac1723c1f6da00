#!/usr/bin/env bash
# The lambda x alpha sweep evaluated on weight averages, as the main table's models are: each
# point's last six checkpoints (iterations 63-108) averaged into runs/swa/sweep_pr_<point>_last6,
# the six averages evaluated into experiments/sweep/averaged (nominal, long-tail),
# and the car-following probe of the alpha-0.5 points and IDM.
#
#   target/release/rtr sweep --config experiments/sweep/rtr.toml --out runs/sweep_pr --scenarios runs/scenarios
#   cargo build --release --bins --examples && experiments/sweep/average.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
rtr=target/release/rtr
probe=target/release/examples/car_following
sweep=runs/sweep_pr
out=experiments/sweep/averaged
for tool in "$rtr" "$probe"; do
    [ -x "$tool" ] || {
        echo "average.sh: $tool not found; build it first with: cargo build --release --bins --examples" >&2
        exit 2
    }
done
points=(lambda0_alpha0 lambda1_alpha0.5 lambda5_alpha0.5 lambda10_alpha0.5 lambda5_alpha0.3 lambda5_alpha0.7)
for p in "${points[@]}"; do # every point checked before any is averaged
    [ -f "$sweep/$p/policy.bpk" ] || {
        echo "average.sh: $sweep/$p has not finished; run the sweep first (it resumes)" >&2
        exit 2
    }
done
averages=()
for p in "${points[@]}"; do
    avg=runs/swa/sweep_pr_${p}_last6
    sources=()
    for i in 108 099 090 081 072 063; do sources+=(--checkpoint "$sweep/$p/checkpoints/iter-000$i"); done
    rm -rf "$avg"
    $rtr model average "${sources[@]}" --out "$avg"
    averages+=("$avg")
done
evals=()
for a in "${averages[@]}"; do evals+=(--checkpoint "$a"); done
$rtr eval "${evals[@]}" --set nominal,longtail --scenarios runs/scenarios --out "$out"
# The probe: does the follower brake for a slower car ahead as lambda grows (alpha 0.5)?
$probe --idm "${averages[0]}" "${averages[1]}" "${averages[2]}" "${averages[3]}" >"$out/car_following.md.tmp"
mv "$out/car_following.md.tmp" "$out/car_following.md"
