#!/usr/bin/env bash
# The lambda x alpha sweep evaluated on weight averages, as the main table's models are: each
# point's last six checkpoints (iterations 675-810, one per epoch) averaged into
# runs/swa/sweep_<point>, evaluated with the main table's IL (models/il_main, the points' warm
# start) into experiments/sweep/averaged (nominal, long-tail, OOD), and the car-following probe
# of IL, the points and IDM.
#
#   target/release/rtr sweep --config experiments/sweep/rtr.toml --points 1:0.5,5:0.5,10:0.5 --out runs/sweep --scenarios runs/scenarios
#   cargo build --release --bins --examples && experiments/sweep/average.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
rtr=target/release/rtr
probe=target/release/examples/car_following
sweep=runs/sweep
out=experiments/sweep/averaged
for tool in "$rtr" "$probe"; do
    [ -x "$tool" ] || {
        echo "average.sh: $tool not found; build it first with: cargo build --release --bins --examples" >&2
        exit 2
    }
done
points=(lambda1_alpha0.5 lambda5_alpha0.5 lambda10_alpha0.5)
for p in "${points[@]}"; do # every point checked before any is averaged
    [ -f "$sweep/$p/policy.bpk" ] || {
        echo "average.sh: $sweep/$p has not finished; run the sweep first (it resumes)" >&2
        exit 2
    }
done
averages=()
for p in "${points[@]}"; do
    avg=runs/swa/sweep_${p}
    sources=()
    for i in 810 783 756 729 702 675; do sources+=(--checkpoint "$sweep/$p/checkpoints/iter-000$i"); done
    rm -rf "$avg"
    $rtr model average "${sources[@]}" --out "$avg"
    averages+=("$avg")
done
evals=(--checkpoint models/il_main)
for a in "${averages[@]}"; do evals+=(--checkpoint "$a"); done
$rtr eval "${evals[@]}" --set nominal,longtail,ood --scenarios runs/scenarios --out "$out"
# The probe: does the follower brake for a slower car ahead as lambda grows?
$probe --idm models/il_main "${averages[@]}" >"$out/car_following.md.tmp"
mv "$out/car_following.md.tmp" "$out/car_following.md"
