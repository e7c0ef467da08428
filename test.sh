#!/usr/bin/env bash
# The tests, as CI runs them (.ci/run): installs what they need where it is missing
# (./setup.sh --tests), then runs the whole workspace's tests. Arguments go to cargo test.
set -euo pipefail
cd "$(dirname "$0")"
./setup.sh --tests
# No incremental compilation: a test run builds once, and its caches would only take disk.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
cargo test --workspace "$@"
