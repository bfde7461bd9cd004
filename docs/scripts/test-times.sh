#!/usr/bin/env bash
# Prints the wall time of every integration test, longest first, with the totals per module: the
# figures behind CI-time work (the whole CI must stay under 30 minutes on 2 cores). libtest's
# per-test times (`--report-time`, JSON output) are unstable options; RUSTC_BOOTSTRAP=1 lets the
# stable test binary accept them (a development tool only: nothing in the build depends on it).
# Times are wall times with the tests sharing the machine's test threads, as in `cargo test`.
# Usage: docs/scripts/test-times.sh [test binary arguments: filters, --ignored, --test-threads N];
# TEST_BINARY=slow times the slow binary (tests/slow) instead of tests/integration.
# About 18 minutes on 2 cores for the whole suite once it is built.
set -euo pipefail
cd "$(dirname "$0")/../.."
target=${TEST_BINARY:-integration}
binary=$(cargo test --release --locked --test "$target" --no-run --message-format json |
    python3 -c 'import json,sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m["target"]["name"] == sys.argv[1] and m.get("executable"):
        print(m["executable"])' "$target")
[ -n "$binary" ] || { echo "test-times.sh: the $target test binary was not built" >&2; exit 1; }
out=$(mktemp)
trap 'rm -f "$out"' EXIT
# A failing test still gets its time listed (the suite line says how many failed).
RUSTC_BOOTSTRAP=1 "$binary" -Z unstable-options --format json --report-time "$@" >"$out" || true
python3 - "$out" <<'PY'
import collections, json, sys
rows, suite = [], None
for line in open(sys.argv[1]):
    try:
        d = json.loads(line)
    except ValueError:
        continue
    if d.get("type") == "test" and "exec_time" in d:
        rows.append((d["exec_time"], d["name"], d["event"]))
    if d.get("type") == "suite" and "exec_time" in d:
        suite = d
rows.sort(reverse=True)
for t, name, event in rows:
    print(f"{t:8.1f} s  {event:6} {name}")
per_module = collections.Counter()
for t, name, _ in rows:
    per_module[name.split("::")[0]] += t
print("\nper module (sum of test wall times):")
for module, t in per_module.most_common():
    print(f"{t:8.1f} s  {module}")
if suite:
    print(f"\nsuite: {suite['exec_time']:.1f} s wall, {suite['passed']} passed, {suite['failed']} failed, "
          f"{suite['ignored']} ignored")
PY
