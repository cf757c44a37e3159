#!/usr/bin/env bash
# How wall time grows with simulated time and with the number of laws (docs/performance.md).
# Run from the workspace root after `cargo build --release`. Prints median wall seconds of 3 runs.
set -euo pipefail
tribo=./target/release/tribo

median3() {
    for _ in 1 2 3; do
        /usr/bin/time -f "%e" "$@" 2>&1 >/dev/null | tail -n 1
    done | sort -n | sed -n 2p
}

echo "simulated time: ramp 1 s to 6000 rpm, then hold (fedem-baseline law set)"
for drive in prescribed pi; do
    for hold in 1 3 7 15; do
        cycle="cycle.segments=[{kind=\"ramp\", to_rpm=6000, duration_s=1}, {kind=\"hold\", duration_s=$hold}]"
        t=$(median3 "$tribo" run crf250r-motored --lawset fedem-baseline --quiet \
            --set "$cycle" --set oil.temperature_c=80 --set "drive={kind=\"$drive\"}")
        echo "$drive $((hold + 1)) s: $t s"
    done
done

echo "laws on the rig: thesis cycle"
one=(--law piston=fedem-friction)
three=("${one[@]}" --law main_a=fedem-friction --law main_b=fedem-friction)
five=("${three[@]}" --law big_end=fedem-friction --law small_end=fedem-friction)
seven=("${five[@]}" --law main_a=coulomb --law big_end=coulomb)
for drive in prescribed pi; do
    d="drive={kind=\"$drive\"}"
    echo "$drive 0: $(median3 "$tribo" run reference-frictionless --quiet --set "$d") s"
    echo "$drive 1: $(median3 "$tribo" run crf250r-motored --quiet --set "$d" "${one[@]}") s"
    echo "$drive 3: $(median3 "$tribo" run crf250r-motored --quiet --set "$d" "${three[@]}") s"
    echo "$drive 5: $(median3 "$tribo" run crf250r-motored --quiet --set "$d" "${five[@]}") s"
    echo "$drive 7: $(median3 "$tribo" run crf250r-motored --quiet --set "$d" "${seven[@]}") s"
done
