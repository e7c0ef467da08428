#!/usr/bin/env bash
# The MRA paper's scenario under the supervisor: the base drives toward an obstacle and the sonar
# stops it at two feet. Starts examples/mra_demo.lua with `modbot up`, drives, shows the result,
# then stops the system with `modbot down`.
set -euo pipefail
cd "$(dirname "$0")/.."
B=target/release
export MODBOT_DOMAIN=mra_demo
$B/modbot check examples/mra_demo.lua
$B/modbot up examples/mra_demo.lua & UP=$!
trap 'kill $UP 2>/dev/null || true' EXIT
until $B/modbot call sonar.ranges >/dev/null 2>&1; do sleep 0.1; done
$B/modbot ls
echo "> modbot call mobility.forward 10"; $B/modbot call mobility.forward 10
until [ "$($B/modbot bb mobility moving)" = "false" ]; do sleep 0.2; done
echo "> modbot bb mobility"; $B/modbot bb mobility
$B/modbot down
wait $UP
