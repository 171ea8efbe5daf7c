#!/usr/bin/env bash
# The closed-loop example: sim_node in lock-step (E402B + 32 Shimmns, paper scenario 6, from
# 80 km/h) driven by examples/speed_controller.py to 40 km/h; the run is recorded, then reported.
#
#   examples/run_speed_control.sh [RUN_DIR] [controller parameters...]
#   examples/run_speed_control.sh runs/hold50 -p target_speed_kmh:=50.0 -p duration_s:=240.0
#
# RUN_DIR defaults to runs/speed_control_<date>-<time>; NS (default /train1) is the namespace of
# both nodes. Ctrl-C stops both nodes cleanly (the recording is closed properly).
set -euo pipefail
cd "$(dirname "$0")/.."
./dev.sh setup                          # the project's venv, created on first use
BIN="$PWD/${LTD_VENV:-.venv}/bin"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
NS=${NS:-/train1}
run_dir=${1:-runs/speed_control_$(date +%Y%m%d-%H%M%S)}
shift || true

stop() {  # SIGINT to a node's process group (the ROS Python bootstrap re-executes once)
  local pid=$1
  if [ "$pid" -gt 0 ] && kill -0 "$pid" 2>/dev/null; then
    kill -INT -- "-$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  fi
}

set -m                                  # every node in its own process group
sim_pid=0 ctl_pid=0
trap 'stop "$ctl_pid"; stop "$sim_pid"' EXIT
trap 'exit 130' INT TERM                # runs the EXIT trap

# chunk_s is the control period: one ~/step = one chunk
"$BIN/sim_node" --ros-args -r __ns:="$NS" -r /clock:="$NS/clock" \
  -p consist:=scenario_6 -p initial_speed_kmh:=80.0 -p lockstep:=true -p chunk_s:=0.1 \
  -p record:=true -p record_dir:="$run_dir" &
sim_pid=$!
"$BIN/python" examples/speed_controller.py --ros-args -r __ns:="$NS" "$@" &
ctl_pid=$!

status=0
wait "$ctl_pid" || status=$?
stop "$sim_pid"                         # closes the recording
trap - EXIT
[ "$status" -eq 0 ] || { echo "speed_controller failed (exit status $status)" >&2; exit "$status"; }
echo
exec "$BIN/ltd-brake" report "$run_dir"
