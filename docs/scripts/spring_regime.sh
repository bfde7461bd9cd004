#!/usr/bin/env bash
# Re-runs the spring-contact regime table of docs/src/design/young-dupre.md: R = 2 µm doublets, l_min = c =
# 0.2 µm, w/(2γ) = 0.1, 0.3, 0.5, from touching spheres and from an over-adhered start, with normal
# relaxation and with full forces. One key=value line per run (examples/spring_regime.rs); ~1–3 min per run
# on one core. Usage: docs/scripts/spring_regime.sh [more spring_regime options, e.g. --radius 5 --lmin 0.4]
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --example spring_regime
for start in touch over; do
    for ratio in 0.1 0.3 0.5; do
        for normal in "" --normal; do
            target/release/examples/spring_regime --ratio "$ratio" --start "$start" $normal "$@"
        done
    done
done
