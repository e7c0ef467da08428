#!/usr/bin/env bash
# The MRA paper's scenario: the base drives toward an obstacle and the sonar stops it at two feet.
set -euo pipefail
cd "$(dirname "$0")/.."
B=target/release
export MODBOT_DOMAIN=mra_demo_$$
$B/modbot-sonar --obstacle 3,0 & SONAR=$!
$B/modbot-mobility & MOBILITY=$!
trap 'kill $SONAR $MOBILITY 2>/dev/null; wait' EXIT
until $B/modbot call sonar.ranges >/dev/null 2>&1; do sleep 0.1; done
$B/modbot ls
echo "> modbot call mobility.forward 10"; $B/modbot call mobility.forward 10
until [ "$($B/modbot bb mobility moving)" = "false" ]; do sleep 0.2; done
echo "> modbot bb mobility"; $B/modbot bb mobility
