#!/usr/bin/env bash
# Print which top-level modules of src/ each module uses (code lines only, comments skipped), for the
# Architecture chapter of the book. Run from anywhere: docs/module-graph.sh
set -euo pipefail
cd "$(dirname "$0")/../src"
for dir in */; do
    m=${dir%/}
    uses=$(grep -rhE 'crate::[a-z_]+' "$m" --include='*.rs' | grep -vE '^\s*//' |
        grep -oE 'crate::[a-z_]+' | sed 's/crate:://' | sort -u | grep -vx "$m" | tr '\n' ' ' || true)
    uses=${uses% }
    printf "%-11s uses %s\n" "$m" "${uses:-nothing}"
done
