#!/usr/bin/env bash
# Runs one fuzz target until it has executed at least RUNS inputs in total, restarting
# libFuzzer after each crash (the input is kept under fuzz/artifacts/TARGET/), and prints
# the executions and crashes counted from libFuzzer's own final statistics.
# Usage (from the repository root, after `RUSTC_BOOTSTRAP=1 cargo fuzz build`):
#   fuzz/tools/campaign.sh TARGET RUNS [LOG]
set -euo pipefail
target=$1
goal=$2
log=${3:-/dev/stderr}
cd "$(dirname "$0")/.."
binary=target/x86_64-unknown-linux-gnu/release/$target
mkdir -p "corpus/$target" "artifacts/$target"
done_runs=0
crashes=0
while ((done_runs < goal)); do
    left=$((goal - done_runs))
    out=$(mktemp)
    status=0
    "$binary" -artifact_prefix="artifacts/$target/" -runs="$left" -timeout=10 -max_len=8192 \
        -print_final_stats=1 "corpus/$target" "seeds/$target" >"$out" 2>&1 || status=$?
    ran=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$out" | grep -o '[0-9]*$' || echo 0)
    grep -E 'SUMMARY|Test unit written|stat::' "$out" >>"$log" || true
    rm -f "$out"
    done_runs=$((done_runs + ran))
    if ((status != 0)); then
        crashes=$((crashes + 1))
        # A crash within the first few inputs is one of the corpus or seed files failing
        # again: restarting would only repeat it.
        if ((ran < 1000)); then
            echo "$target: libFuzzer exited with $status after $ran inputs: the corpus itself fails (see fuzz/artifacts/$target/)" >&2
            exit 1
        fi
    fi
done
echo "$target: $done_runs executions, $crashes crashes"
