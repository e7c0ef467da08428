#!/usr/bin/env bash
# Runs every fuzz target (or those in $TARGETS) for RUNS executions each (default 10 million),
# starting from the corpus in the repository, and prints executions and crashes per target.
# Inputs that reach new code are merged back into fuzz/corpus/<target>, which the ordinary
# test suite replays (ipc_schema/tests/fuzz_corpus.rs, runtime/system/tests/fuzz_corpus.rs).
# A hang (one input over 10 s) or a crash stops that target and leaves the input in
# fuzz/artifacts/<target>/. Needs the nightly toolchain and cargo-fuzz:
#   rustup toolchain install nightly && cargo install cargo-fuzz
#   bash fuzz/run.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")"
RUNS=${1:-10000000}
TARGETS=${TARGETS:-"frame values snapshot heartbeat grid directory relay switch status latency bus grid_spec description"}
cargo +nightly fuzz build -O >/dev/null
printf '%-12s %12s %9s %8s\n' target executions seconds crashes
status=0
for t in $TARGETS; do
    work=target/corpus/$t
    mkdir -p "$work" "corpus/$t"
    log=target/$t.log
    crashes=0
    seeds=()
    if [ "$t" = description ]; then
        # The example systems seed the descriptions (read, never written to).
        seeds=(../examples ../examples/arm ../examples/first_module)
    fi
    if ! cargo +nightly fuzz run -O "$t" "$work" "corpus/$t" "${seeds[@]}" -- \
        -runs="$RUNS" -timeout=10 -print_final_stats=1 >"$log" 2>&1; then
        crashes=1
        status=1
    fi
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
    secs=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | grep -o 'in [0-9]*' | grep -o '[0-9]*' || echo '?')
    printf '%-12s %12s %9s %8s\n' "$t" "$runs" "$secs" "$crashes"
    # Keep what reached new code, for the replay test.
    cargo +nightly fuzz run -O "$t" "corpus/$t" "$work" -- -merge=1 >>"$log" 2>&1 || true
done
exit $status
