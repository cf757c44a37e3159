#!/bin/sh
# Regenerate the law gallery (docs/laws/README.md): one SVG per bundled law, drawn by
# `tribo plot-law` with the parameters in docs/laws/params/ on the joint each law is used on.
# Run from the workspace root after `cargo build --release --workspace`.
set -eu
tribo=${TRIBO:-target/release/tribo}
while read -r law joint; do
    "$tribo" plot-law "$law" --params "docs/laws/params/$law.toml" --joint "$joint" \
        --out "docs/laws/$law.svg"
done <<'LAWS'
coulomb piston
c-coulomb piston
fedem-friction big_end
polyline-damper main_a
stribeck-duty piston
petroff-journal main_a
mixed-film piston
rolling-bearing main_a
lugre piston
plain-journal main_a
crank-churning main_a
piston-skirt piston
ring-pack piston
lip-seal main_a
crank-windage main_a
LAWS
