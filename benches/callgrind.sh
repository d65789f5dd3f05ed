#!/usr/bin/env bash
# Instructions per step, counted by callgrind (stable on a noisy machine): the difference between runs of
# N1 and N2 steps divided by N2 - N1, so set-up (table building) cancels out.
# Usage: benches/callgrind.sh [compensator|extended|controller|closed_loop|hysteresis]
set -euo pipefail
cd "$(dirname "$0")/.."
what="${1:-compensator}"
cargo build --release -p bmr-bench --example step_count >/dev/null 2>&1
bin=target/release/examples/step_count
count() {
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" "$1" "$what" 2>&1 \
    | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
n1=20000
n2=220000
i1=$(count $n1)
i2=$(count $n2)
echo "$what: $(( (i2 - i1) / (n2 - n1) )) instructions per step (callgrind, $n1 vs $n2 steps)"
